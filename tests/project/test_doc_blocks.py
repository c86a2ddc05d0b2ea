"""Every fenced block of README.md and docs/*.md runs, or is compared with what rac really prints
or writes: a page is followed as a reader would, block by block, in a scratch copy of the project's
``examples/``, ``stdlib/`` and ``tests/`` folders (so outputs never land in the checkout).

How each block is taken, by its language and the HTML comment on the line before its fence:

- ``ra``: a complete automaton must pass ``rac check`` (or fail with the code of a preceding
  ``<!-- expect: CODE -->``); ``<!-- file: NAME.ra -->`` also saves it as NAME.ra for the page's
  later commands. A fragment must parse inside an automaton (``<!-- fragment: model -->``: inside
  its ``model`` block).
- ``python``: runs (``python -c``) with the scratch folder as working directory and ``tests/`` on the
  import path.
- ``sh``: each command line runs and must exit 0 (a trailing ``# ... exit N`` comment names another
  status). The README's install and test commands are what CI itself runs; ``python benchmarks/...``
  lines are benchmarks, run by their own command (docs/benchmarks.md), never by the tests.
- ``text`` beginning with ``$ COMMAND``: a transcript; the command runs and its output must equal
  the block's lines (timings and rates masked, table columns about time dropped).
  ``<!-- compare: the table below -->`` compares the markdown table after the block instead.
- ``<!-- excerpt of: PATH -->`` / ``<!-- excerpt of output: COMMAND -->``: every run of lines
  between ``...`` lines appears, in order, in the file (of the checkout, or written by an earlier
  command of the page) or in the command's output.
- ``<!-- not run: REASON -->``: shown only (UPPAAL's verifier is closed source; a quoted paper).
- the ``case``, ``excerpt`` and ``output`` regions of docs/checks.md and docs/diagnostics.md are
  generated from tests/diagnostics and compared there (tests/check/test_diagnostics.py).

Any other block fails the test: a new block must say how it is checked.
"""

from __future__ import annotations

import html
import importlib
import os
import re
import shlex
import shutil
import subprocess
import sys
from dataclasses import dataclass, field
from pathlib import Path

import pytest
import test_examples
from test_examples import Block, code_blocks

import rac
from rac.lang.parser import ParseFailure, parse_text

REPO = Path(__file__).resolve().parents[2]
PAGES = [REPO / "README.md", *sorted((REPO / "docs").glob("*.md"))]
#: The folders a page's commands may read, copied into the scratch folder.
COPIED = ("benchmarks", "examples", "stdlib", "tests")

_ANNOTATION = re.compile(r"^<!--\s*([a-z][a-z ]*?)\s*:\s*(.*?)\s*-->$")
_REGION_START = re.compile(r"^<!--\s*(case|excerpt|output):")
_REGION_END = re.compile(r"^<!--\s*end (case|excerpt|output)\s*-->$")
_EXIT = re.compile(r"#.*\bexit (\d+)\b")
#: Timings and rates differ from run to run.
_DURATION = re.compile(r"\b\d[\d,]*(\.\d+)?\s?(ms|s|min)\b")
_RATE = re.compile(r"\b\d[\d,.]*\s?[kM]?(states|episodes)?/s\b")


def _annotation(lines: list[str], fence: int) -> tuple[str, str] | None:
    """The ``<!-- key: value -->`` on the last non-blank line before the fence (0-based), if any."""
    k = fence - 1
    while k >= 0 and not lines[k].strip():
        k -= 1
    if k >= 0 and (found := _ANNOTATION.match(lines[k].strip())):
        return found.group(1), found.group(2)
    return None


def _in_generated_region(lines: list[str], fence: int) -> bool:
    """Whether the fence lies in a ``case``, ``excerpt`` or ``output`` region (docs/checks.md, docs/diagnostics.md)."""
    for previous in reversed(lines[:fence]):
        if _REGION_END.match(previous.strip()):
            return False
        if _REGION_START.match(previous.strip()):
            return True
    return False


def _table_after(lines: list[str], block: Block) -> list[str]:
    """The markdown table that follows ``block``'s closing fence (blank lines before it skipped)."""
    k = block.line  # 0-based index of the first line after the opening fence
    while not lines[k].strip().startswith("```"):
        k += 1
    k += 1
    while k < len(lines) and not lines[k].strip():
        k += 1
    table = []
    while k < len(lines) and lines[k].startswith("|"):
        table.append(lines[k])
        k += 1
    return table


def normalised(text: str) -> list[str]:
    """Lines with timings and rates masked, spaces collapsed, and table columns about time dropped."""
    result: list[str] = []
    timing_columns: set[int] = set()
    for line in text.splitlines():
        line = line.rstrip()
        if line.startswith("|"):
            cells = [c.strip() for c in line.strip("|").split("|")]
            if any("time" in c for c in cells):
                timing_columns = {i for i, c in enumerate(cells) if "time" in c}
            line = "|".join(c for i, c in enumerate(cells) if i not in timing_columns)
        line = _RATE.sub("R/s", _DURATION.sub("T", line))
        result.append(" ".join(line.split()))
    while result and not result[-1]:
        result.pop()
    return result


def _flat_xml(text: str) -> list[str]:
    """XML as one line without layout: coordinates, nails, transition ids and the space between tags dropped."""
    text = re.sub(r'\s(x|y)="-?\d+"', "", text)
    text = re.sub(r"<nail\s*/>", "", text)
    text = re.sub(r'<transition id="\w+"', "<transition", text)
    return ["".join(line.strip() for line in text.splitlines())]


def contains_excerpt(source: str, excerpt: str, *, xml: bool = False) -> str | None:
    """None when every run of ``excerpt``'s lines between ``...`` lines appears, in order, as
    consecutive lines of ``source`` (both :func:`normalised`, XML entities read; ``xml``: as one
    line each, without layout); else the first run that does not."""
    have = [line for line in normalised(html.unescape(source)) if line]
    chunks: list[list[str]] = [[]]
    for line in normalised(html.unescape(excerpt)):
        if line in ("...", "…"):
            chunks.append([])
        elif line:
            chunks[-1].append(line)
    if xml:
        have = _flat_xml("\n".join(have))
        chunks = [_flat_xml("\n".join(chunk)) for chunk in chunks]
    position = 0
    for chunk in filter(lambda c: any(c), chunks):
        if xml:  # within the one line: a substring, after the previous one
            found = have[0].find(chunk[0], position)
            if found < 0:
                return chunk[0]
            position = found + len(chunk[0])
            continue
        found = next((i for i in range(position, len(have) - len(chunk) + 1) if have[i:i + len(chunk)] == chunk), None)
        if found is None:
            return "\n".join(chunk)
        position = found + len(chunk)
    return None


@dataclass
class Reader:
    """Follows one page in a scratch folder, collecting what does not hold."""

    page: Path
    scratch: Path
    problems: list[str] = field(default_factory=list)
    #: What each command printed: a page that runs a command twice (a list of commands, then its
    #: transcript) runs it once.
    ran: dict[str, subprocess.CompletedProcess[str]] = field(default_factory=dict)

    def env(self) -> dict[str, str]:
        rac_parent = str(Path(rac.__file__).resolve().parent.parent)
        return {**os.environ, "PYTHONPATH": os.pathsep.join([rac_parent, str(self.scratch / "tests"),
                                                             str(self.scratch / "tests" / "support")]),
                "PYTHONIOENCODING": "utf-8", "COLUMNS": "100"}

    def run(self, command: str, block: Block, *, again: bool = False) -> subprocess.CompletedProcess[str] | None:
        """One command line as a reader types it (``rac`` and ``python`` are this Python's); a command
        the page ran before is not run twice unless ``again`` (its input changed)."""
        words = shlex.split(command, comments=True)
        key = " ".join(words)
        if key in self.ran and not again:
            return self.ran[key]
        if words[0] == "rac":
            words = [sys.executable, "-m", "rac", *words[1:]]
        elif words[0] in ("python", "python3"):
            words = [sys.executable, *words[1:]]
        else:
            self.problems.append(f"{block.id}: `{words[0]}` is not a command the docs' tests can run "
                                 "(mark the block <!-- not run: why -->)")
            return None
        self.ran[key] = subprocess.run(words, cwd=self.scratch, env=self.env(), capture_output=True, text=True,
                                       timeout=600)
        return self.ran[key]

    def fail(self, block: Block, message: str) -> None:
        self.problems.append(f"{block.id}: {message}")

    # ------------------------------------------------------------ by kind
    def ra(self, block: Block, note: tuple[str, str] | None) -> None:
        if note is not None and note[0] == "file":
            (self.scratch / note[1]).write_text(block.text, encoding="utf-8")
        code = re.sub(r"//[^\n]*|/\*.*?\*/", "", block.text, flags=re.S).lstrip()
        if not code.startswith("automaton"):
            inner = f"model {{\n{block.text}\n}}\n" if note == ("fragment", "model") else block.text
            try:
                parse_text(f"automaton Fragment {{\n{inner}\n}}\n", "<fragment>")
            except ParseFailure as exc:
                self.fail(block, f"the fragment does not parse: {exc}")
            return
        path = self.scratch / (note[1] if note is not None and note[0] == "file" else "block.ra")
        path.write_text(block.text, encoding="utf-8")
        checked = self.run(f"rac check {shlex.quote(str(path))}", block, again=True)
        assert checked is not None
        expect = note[1] if note is not None and note[0] == "expect" else None
        report = checked.stdout + checked.stderr
        if expect is None and checked.returncode != 0:
            self.fail(block, f"should pass `rac check`:\n{report}")
        elif expect is not None and (f"[{expect}]" not in report
                                     or checked.returncode != (0 if expect.startswith("W") else 1)):
            self.fail(block, f"should report {expect}:\n{report}")

    def python(self, block: Block) -> None:
        result = subprocess.run([sys.executable, "-c", block.text], cwd=self.scratch, env=self.env(),
                                capture_output=True, text=True, timeout=600)
        if result.returncode != 0:
            self.fail(block, f"the Python block failed:\n{result.stdout}\n{result.stderr}")

    def sh(self, block: Block) -> None:
        for line in block.text.splitlines():
            if not line.strip() or line.lstrip().startswith("#"):
                continue
            if line.startswith("python benchmarks/"):
                continue  # a benchmark: its own command runs it (docs/benchmarks.md)
            if line.startswith("verifyta "):
                continue  # UPPAAL's verifier is closed source: tests/targets/test_utap.py parses rac's files
            result = self.run(line, block)
            want = int(found.group(1)) if (found := _EXIT.search(line)) else 0
            if result is not None and result.returncode != want:
                self.fail(block, f"`{line}` exited {result.returncode}, not {want}:\n{result.stdout}\n{result.stderr}")

    def transcript(self, block: Block, note: tuple[str, str] | None, lines: list[str]) -> None:
        text = block.text.splitlines()
        command = text[0][2:]
        result = self.run(command, block)
        if result is None:
            return
        expected = "\n".join(text[1:])
        if note == ("compare", "the table below"):
            expected = "\n".join(_table_after(lines, block))
            got = normalised("\n".join(line for line in result.stdout.splitlines() if line.startswith("|")))
            if got != normalised(expected):
                self.fail(block, f"`{command}` prints another table:\n" + "\n".join(got))
            return
        if normalised(result.stdout + result.stderr) != normalised(expected):
            self.fail(block, f"`{command}` printed:\n{result.stdout}{result.stderr}")

    def excerpt(self, block: Block, source: str) -> None:
        if source.startswith("output: ") or source.startswith("$ "):
            command = source.split(" ", 1)[1]
            result = self.run(command, block)
            if result is None:
                return
            text = result.stdout + result.stderr
        else:
            path = self.scratch / source if (self.scratch / source).exists() else REPO / source
            if not path.exists():
                self.fail(block, f"the excerpt's source {source} does not exist")
                return
            text = path.read_text(encoding="utf-8")
            if path.suffix == ".xml" and block.language != "xml":  # code from a model's declarations
                text = re.sub(r"<[^>]+>", "", text)  # before the entities are read: `&lt;` is code
        shown = block.text
        if shown.startswith("$ "):  # the command is the annotation's
            shown = shown.split("\n", 1)[1]
        missing = contains_excerpt(text, shown, xml=block.language == "xml")
        if missing is not None:
            self.fail(block, f"not in {source}:\n{missing}")

    def read(self) -> None:
        lines = self.page.read_text(encoding="utf-8").splitlines()
        for block in code_blocks(self.page):
            fence = block.line - 1
            if _in_generated_region(lines, fence):
                continue
            note = _annotation(lines, fence)
            key = note[0] if note else None
            if key == "not run":
                if not note or not note[1]:
                    self.fail(block, "`not run` needs a reason")
                continue
            if key == "excerpt of":
                assert note is not None
                self.excerpt(block, note[1])
            elif key == "excerpt of output":
                assert note is not None
                self.excerpt(block, "output: " + note[1])
            elif block.language == "ra":
                self.ra(block, note)
            elif block.language == "python":
                self.python(block)
            elif block.language == "sh":
                self.sh(block)
            elif block.text.startswith("$ "):
                self.transcript(block, note, lines)
            else:
                self.fail(block, f"a `{block.language}` block that nothing checks: run it, or mark it <!-- "
                                 "excerpt of: PATH -->, <!-- excerpt of output: COMMAND --> or <!-- not run: why -->")


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_page_blocks_hold(page: Path, tmp_path: Path) -> None:
    for name in COPIED:
        shutil.copytree(REPO / name, tmp_path / name, ignore=shutil.ignore_patterns("*.out", "__pycache__",
                                                                                    ".hypothesis", "golden"))
    reader = Reader(page, tmp_path)
    reader.read()
    assert not reader.problems, "\n\n".join(reader.problems)


def test_a_block_without_a_language_is_checked_too(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    # a fence without a language was not seen at all: about 40 blocks were checked by nothing
    monkeypatch.setattr(test_examples, "REPO", tmp_path)  # where a block's place is named from
    page = tmp_path / "page.md"
    page.write_text("Text.\n\n```\nsome output\n```\n\n<!-- not run: shown only -->\n```\nmore\n```\n",
                    encoding="utf-8")
    assert [(b.line, b.language) for b in code_blocks(page)] == [(3, ""), (8, "")]
    reader = Reader(page, tmp_path)
    reader.read()
    assert len(reader.problems) == 1 and "page.md:3" in reader.problems[0]
    assert "nothing checks" in reader.problems[0]


# ---------------------------------------------------------------- fences
_ANY_FENCE = re.compile(r"^\s*(`{3,})")


def unclosed_fence(text: str) -> int | None:
    """The 1-based line of a code fence that nothing closes (the rest of the page would render as
    code, and :func:`code_blocks` would not see a block opened there), or None."""
    opened: tuple[int, str] | None = None
    for number, line in enumerate(text.splitlines(), 1):
        if not (found := _ANY_FENCE.match(line)):
            continue
        if opened is None:
            opened = number, found.group(1)
        elif found.group(1).startswith(opened[1]) and not line.strip().strip("`"):
            opened = None
    return None if opened is None else opened[0]


@pytest.mark.parametrize("page", [*PAGES, *sorted((REPO / "examples").glob("*/README.md"))],
                         ids=lambda p: str(p.relative_to(REPO)))
def test_every_fence_is_closed(page: Path) -> None:
    line = unclosed_fence(page.read_text(encoding="utf-8"))
    assert line is None, f"{page.relative_to(REPO)}:{line}: this code fence is never closed"


def test_an_unclosed_fence_is_found() -> None:
    assert unclosed_fence("a\n```sh\nrac check x.ra\n```\nb\n") is None
    assert unclosed_fence("```\nout\n```\n```\n\n## Next\n") == 4  # a stray closing fence opens a block
    assert unclosed_fence("```python\nx = 1\n") == 1
    assert unclosed_fence("````md\n```sh\n```\n````\n") is None  # a longer fence holds shorter ones


# ---------------------------------------------------------------- links between the pages
#: A markdown link to a page of the checkout (not a URL), with its anchor if any.
_LOCAL_LINK = re.compile(r"\]\((?![a-z]+:)(?P<path>[^)#\s]*)(?:#(?P<anchor>[^)\s]+))?\)")


def slug(heading: str) -> str:
    """GitHub's anchor for a heading: lower case, punctuation dropped, spaces as ``-``."""
    text = re.sub(r"\[([^\]]*)\]\([^)]*\)", r"\1", heading).strip().lower()
    return re.sub(r"[^\w\- ]", "", text).replace(" ", "-")


def anchors(page: Path) -> set[str]:
    """The anchors of a page: its headings' (outside code blocks, numbered when repeated) and its ``<a id>``s."""
    text = re.sub(r"^\s*```.*?^\s*```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    found: set[str] = set(re.findall(r'<a id="([^"]+)"', text))
    for heading in re.findall(r"^#{1,6} (.+)$", text, re.M):
        base = slug(heading)
        name, n = base, 0
        while name in found:
            n += 1
            name = f"{base}-{n}"
        found.add(name)
    return found


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_links_reach_their_anchor(page: Path) -> None:
    """Every link to a page of the checkout names a file that exists, and an anchor the page has
    (a diagnostic code's section: ``diagnostics.md#e0402``)."""
    text = re.sub(r"^\s*```.*?^\s*```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    text = re.sub(r"`[^`\n]*`", "", text)  # code: `Pr[<=30](...)` is no link
    broken = []
    for match in _LOCAL_LINK.finditer(text):
        target = (page.parent / match["path"]).resolve() if match["path"] else page
        if not target.exists():
            broken.append(f"{match['path']}: no such file")
        elif match["anchor"] and target.suffix == ".md" and match["anchor"] not in anchors(target):
            broken.append(f"{match['path'] or page.name}#{match['anchor']}: no such anchor")
    assert not broken, f"{page.relative_to(REPO)}: broken links:\n" + "\n".join(broken)


def test_every_image_is_shown() -> None:
    """Every picture in docs/images is shown by a page: experiment_returns.png lay there, referenced
    nowhere, left behind as the figure it showed changed."""
    shown = " ".join(page.read_text(encoding="utf-8") for page in PAGES)
    unused = [image.name for image in sorted((REPO / "docs" / "images").iterdir())
              if f"images/{image.name}" not in shown]
    assert not unused, f"docs/images holds pictures no page shows: {unused}"


#: A dotted name of rac's API in inline code: `rac.check.params.synthesise_parameters`, `rac.load(path)`.
_API_NAME = re.compile(r"`(rac(?:\.[A-Za-z_]\w*)+)")


def resolves(dotted: str) -> bool | None:
    """Whether ``dotted`` names a module of rac or an attribute of one (the longest importable module,
    then attributes); None when a module needs a package that is not installed (an optional extra)."""
    parts = dotted.split(".")
    for k in range(len(parts), 0, -1):
        try:
            found: object = importlib.import_module(".".join(parts[:k]))
        except ImportError as exc:
            # a missing package of an extra, raised as it is or wrapped (rac.learning.sb3 says which extra)
            missing = exc if isinstance(exc, ModuleNotFoundError) else exc.__cause__
            if isinstance(missing, ModuleNotFoundError) and missing.name and missing.name.split(".")[0] != "rac":
                return None
            if not isinstance(exc, ModuleNotFoundError):
                raise
            continue
        for attribute in parts[k:]:
            if not hasattr(found, attribute):
                return False
            found = getattr(found, attribute)
        return True
    return False


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_api_names_exist(page: Path) -> None:
    """Every `rac.x.y` a page names in its prose is a module of rac or an attribute of one
    (docs/benchmarks.md named `rac.compiler.synthesise_parameters` after it moved to rac.check.params)."""
    text = re.sub(r"^\s*```.*?^\s*```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    missing = sorted({name for name in _API_NAME.findall(text) if resolves(name) is False})
    assert not missing, f"{page.relative_to(REPO)} names what rac does not have: {', '.join(missing)}"


def test_api_names_are_resolved(monkeypatch: pytest.MonkeyPatch) -> None:
    assert resolves("rac.check.params.synthesise_parameters") is True
    assert resolves("rac.compiler.synthesise_parameters") is False
    assert resolves("rac.no_such_module") is False

    # an extra that is not installed (CI has no stable-baselines3): rac.learning.sb3 wraps the
    # ModuleNotFoundError in an ImportError naming the extra; the name cannot be judged, not wrong
    def without_sb3(name: str) -> object:
        if name == "rac.learning.sb3":
            try:
                raise ModuleNotFoundError("No module named 'stable_baselines3'", name="stable_baselines3")
            except ModuleNotFoundError as exc:
                raise ImportError("rac.learning.sb3 needs stable-baselines3: pip install 'rac[rl]'") from exc
        return real(name)

    real = importlib.import_module
    monkeypatch.setattr(importlib, "import_module", without_sb3)
    assert resolves("rac.learning.sb3.RacCallback") is None


def glance_codes(table: str) -> set[int]:
    """The code numbers the first column of a "Code | Meaning" table covers: ``E0401, E0402``, and
    ranges ``E0712–W0724`` (every number from the first to the last, whatever its letter)."""
    covered: set[int] = set()
    for row in table.splitlines():
        cells = row.strip("|").split("|")
        for part in cells[0].split(","):
            ends = [int(code[1:]) for code in re.findall(r"[EW]\d{4}", part)]
            if len(ends) == 1 or len(ends) == 2 and "–" in part:
                covered.update(range(ends[0], ends[-1] + 1))
    return covered


def test_language_glance_covers_every_code() -> None:
    """docs/language.md's "Diagnostics at a glance" has a row for every code of docs/diagnostics.md
    (it stopped at E0016's neighbours, E0603, E0713 and skipped the parameters, incentives and targets)."""
    page = (REPO / "docs" / "language.md").read_text(encoding="utf-8")
    table = page.split("## Diagnostics at a glance", 1)[1].split("\n## ", 1)[0]
    codes = re.findall(r"^## ([EW]\d{4}) ", (REPO / "docs" / "diagnostics.md").read_text(encoding="utf-8"), re.M)
    assert codes
    missing = [code for code in codes if int(code[1:]) not in glance_codes(table)]
    assert not missing, f"docs/language.md's diagnostics at a glance leave out {', '.join(missing)}"


def test_glance_ranges_are_read() -> None:
    assert glance_codes("| E0001–E0003 | x |\n| W0108, W0109 | y |\n| E0501 | z |") == {1, 2, 3, 108, 109, 501}


def test_anchors_follow_github() -> None:
    assert slug("E0714 — ego start outside the model's limits") == "e0714--ego-start-outside-the-models-limits"
    assert slug("Input classes: why the checks are exact") == "input-classes-why-the-checks-are-exact"
    assert slug("`assume` excludes every input valuation") == "assume-excludes-every-input-valuation"


# ---------------------------------------------------------------- the comparisons themselves
def test_excerpts_need_their_lines_in_order() -> None:
    source = "a\n  b  c\nd\ne\nf\n"
    assert contains_excerpt(source, "b c\nd\n...\nf\n") is None
    assert contains_excerpt(source, "d\n...\nb c\n") == "b c"  # out of order
    assert contains_excerpt(source, "a\nd\n") == "a\nd"  # not consecutive
    assert contains_excerpt("x &lt; 1 &amp;&amp; y\n", "x < 1 && y\n") is None
    layout = '<a>\n  <b x="1" y="-2">one</b>\n  <c/>\n  <transition id="id3"><d/></transition>\n</a>\n'
    assert contains_excerpt(layout, "<a><b>one</b>\n...\n<transition><d/>", xml=True) is None
    assert contains_excerpt(layout, "<a><b>one</b><transition>", xml=True) == "<a><b>one</b><transition>"


def test_transcripts_mask_timings_and_time_columns() -> None:
    assert normalised("Qd: 1,392,461 states, 3.32 s (412 k/s)\n") == ["Qd: 1,392,461 states, T (R/s)"]
    table = "| a | time (s) | b |\n| --- | --- | --- |\n| 1 | 0.28 | 53,152 |\n"
    assert normalised(table) == ["a|b", "---|---", "1|53,152"]
    assert normalised(table) != normalised(table.replace("53,152", "65,127"))
