"""UPPAAL's own parser in the tests: ``utap_validate`` (UTAP, the parser and type checker inside UPPAAL).

``../shared/tools/uppaal-parser`` beside the checkout builds it (see its README); ``utap_validate -q
FILE.q FILE.xml`` exits 0 when UPPAAL would accept the model and every query, 1 with errors (one
line per problem on stdout), 2 on a usage error.

How the validator is found (once per session, :func:`locate`):

1. ``RAC_UTAP_VALIDATE``: the path of the binary (CI sets it; a path that is not an executable
   file is an error, not a reason to skip);
2. else ``<repo>/../shared/tools/uppaal-parser/build``, run once (it builds the binary the first
   time, about a minute, and prints its path on its last line);
3. else it is unavailable: the tests that need it skip, or fail when ``RAC_REQUIRE_UTAP=1``.

The ``utap`` fixture (tests/conftest.py) hands the tests a :class:`Utap`; every validation that
passes is counted in :data:`COUNTS`, which conftest's ``pytest_terminal_summary`` prints.
"""

from __future__ import annotations

import functools
import os
import re
import subprocess
from dataclasses import dataclass
from pathlib import Path

import pytest

REPOSITORY = Path(__file__).resolve().parents[2]
BUILD = REPOSITORY.parent / "shared" / "tools" / "uppaal-parser" / "build"
ENV_PATH = "RAC_UTAP_VALIDATE"
ENV_REQUIRE = "RAC_REQUIRE_UTAP"
#: The start of the reason every test skips with when the validator is unavailable (conftest counts these).
UNAVAILABLE = "UPPAAL's parser is not available"
BUILD_TIMEOUT = 900.0  # s; the first build takes about a minute
RUN_TIMEOUT = 60.0  # s; one validation takes milliseconds


@dataclass
class Counts:
    """Validations of this session: models and query files accepted, and validations rejected."""

    models: int = 0
    query_files: int = 0
    rejected: int = 0


COUNTS = Counts()


def add_counts(other: dict[str, int]) -> None:
    """Add a pytest-xdist worker's counts (sent as a dict) to this process's :data:`COUNTS`."""
    COUNTS.models += other.get("models", 0)
    COUNTS.query_files += other.get("query_files", 0)
    COUNTS.rejected += other.get("rejected", 0)


@dataclass(frozen=True)
class Located:
    """The validator's path, or why there is none (``path is None``)."""

    path: Path | None
    reason: str = ""


def required() -> bool:
    """``RAC_REQUIRE_UTAP=1``: a missing validator is a test failure (CI), not a skip."""
    return os.environ.get(ENV_REQUIRE, "").strip() not in ("", "0")


@functools.cache
def locate() -> Located:
    """Find (or build) ``utap_validate``; the result is cached for the session."""
    configured = os.environ.get(ENV_PATH, "").strip()
    if configured:
        path = Path(configured)
        if not (path.is_file() and os.access(path, os.X_OK)):
            raise RuntimeError(f"{ENV_PATH}={configured} is not an executable file: unset it, or point it at "
                               f"the path `{BUILD} | tail -1` prints")
        return Located(path)
    if not BUILD.exists():
        return Located(None, f"{UNAVAILABLE}: no ../shared/tools/uppaal-parser beside this checkout and "
                             f"{ENV_PATH} unset (looked for {BUILD})")
    try:
        result = subprocess.run([str(BUILD)], capture_output=True, text=True, timeout=BUILD_TIMEOUT, check=False)
    except (OSError, subprocess.TimeoutExpired) as exc:
        return Located(None, f"{UNAVAILABLE}: running {BUILD} failed: {exc}")
    lines = result.stdout.strip().splitlines()
    if result.returncode != 0 or not lines:
        tail = "\n".join(result.stderr.strip().splitlines()[-15:])
        return Located(None, f"{UNAVAILABLE}: {BUILD} exited with {result.returncode}:\n{tail}")
    path = Path(lines[-1].strip())
    if not (path.is_file() and os.access(path, os.X_OK)):
        return Located(None, f"{UNAVAILABLE}: {BUILD} printed `{path}`, which is not an executable file")
    return Located(path)


def unavailable(reason: str) -> None:
    """Skip the calling test (fail it instead when ``RAC_REQUIRE_UTAP=1``)."""
    if required():
        pytest.fail(f"{reason} ({ENV_REQUIRE}=1: the tests must run with it)", pytrace=False)
    pytest.skip(reason)


# ---------------------------------------------------------------- validating
#: ``... in /nta/template[4]/location[2]/label[1] at line 1 column 106 to line 1 column 224``
_XPATH = re.compile(r" in (/nta\S*) at line (\d+) column (\d+) to line (\d+) column (\d+)")
#: ``out.q:12: error: ... at line 1 column 4 to line 1 column 7``
_QUERY_LINE = re.compile(r"^(?P<file>\S+\.q):(?P<line>\d+): .* at line (\d+) column (\d+) to line (\d+) column (\d+)")


def _excerpt(text: str, line: int, start: int, end_line: int, end: int) -> str:
    """Line ``line`` of ``text`` (1-based) with carets under columns ``start`` to ``end`` (UTAP's
    columns: 0-based, the end excluded); a long line is cut to the part around them."""
    lines = text.splitlines() or [""]
    if not 1 <= line <= len(lines):
        return ""
    shown = lines[line - 1]
    start = min(max(0, start), len(shown))
    stop = min(end if end_line == line else len(shown), len(shown))
    first, last = max(0, start - 40), min(len(shown), max(stop, start + 1) + 40)
    prefix, suffix = ("..." if first else ""), ("..." if last < len(shown) else "")
    carets = " " * (len(prefix) + start - first) + "^" * max(1, stop - start)
    return f"        {prefix}{shown[first:last]}{suffix}\n        {carets}"


def _model_element_text(xml: str, xpath: str) -> str | None:
    """The text of the element at ``xpath`` in ``xml`` (lxml), None when it cannot be found."""
    try:
        from lxml import etree

        found = etree.fromstring(xml.encode("utf-8")).xpath(xpath)
    except Exception:  # only decorates the message: the validator's output is shown anyway
        return None
    if not found or not hasattr(found[0], "text"):
        return None
    return found[0].text or ""


def explain(output: str, xml: str, queries: str | None) -> str:
    """The validator's output, each problem followed by the text it points at."""
    out = []
    for problem in output.splitlines():
        out.append(problem)
        match = _XPATH.search(problem)
        if match:
            text = _model_element_text(xml, match.group(1))
            if text is not None:
                out.append(_excerpt(text, *map(int, match.groups()[1:])))
            continue
        match = _QUERY_LINE.match(problem)
        if match and queries is not None:
            number = int(match.group("line"))
            query_lines = queries.splitlines()
            if 1 <= number <= len(query_lines):
                excerpt = _excerpt(query_lines[number - 1], 1, *map(int, match.groups()[3:]))
                out.append(excerpt or f"        {query_lines[number - 1]}")
    return "\n".join(line for line in out if line)


class Utap:
    """Runs ``utap_validate`` on emitted text; every test gets its files in a fresh folder."""

    def __init__(self, binary: Path, folder: Path):
        self.binary = binary
        self.folder = folder
        self._serial = 0

    def validate(self, xml: str, queries: str | None = None, name: str = "model") -> str:
        """Write ``NAME.xml`` (and ``NAME.q``), validate them and assert that UPPAAL accepts both.

        The assertion message holds the validator's full output and, for each problem, the line of
        the model or query file it names. Returns the output (``0 error(s), ...``) when accepted.
        """
        self._serial += 1
        folder = self.folder / f"{self._serial:04d}"
        folder.mkdir(parents=True)
        safe = re.sub(r"[^\w.-]+", "_", name) or "model"
        model = folder / f"{safe}.xml"
        model.write_text(xml, encoding="utf-8")
        command = [str(self.binary)]
        if queries is not None:
            query_file = folder / f"{safe}.q"
            query_file.write_text(queries, encoding="utf-8")
            command += ["-q", query_file.name]
        command.append(model.name)
        result = subprocess.run(command, capture_output=True, text=True, timeout=RUN_TIMEOUT, check=False,
                                cwd=folder)
        output = (result.stdout + result.stderr).strip()
        if result.returncode != 0:
            COUNTS.rejected += 1
            kind = "rejected" if result.returncode == 1 else f"could not check (exit {result.returncode})"
            what = f"{safe}.xml" + (f" with {safe}.q" if queries is not None else "")
            raise AssertionError(f"UPPAAL's parser (utap_validate) {kind} {what} (files kept in {folder}):\n"
                                 + explain(output, xml, queries))
        COUNTS.models += 1
        if queries is not None:
            COUNTS.query_files += 1
        return output

    def validate_files(self, xml: Path, queries: Path | None = None) -> str:
        """:meth:`validate` of files rac wrote (``FILE.xml`` and its ``FILE.q``)."""
        return self.validate(xml.read_text(encoding="utf-8"),
                             None if queries is None else queries.read_text(encoding="utf-8"), xml.stem)


def summary_line(skipped: int, failed: int = 0) -> str | None:
    """The line conftest prints at the end of the session: how many validations passed (and failed),
    or how many tests skipped (or failed, under ``RAC_REQUIRE_UTAP=1``) for want of the validator;
    None when no test asked for it."""
    if COUNTS.models or COUNTS.rejected:
        line = (f"UPPAAL's parser (utap_validate) accepted {COUNTS.models} model{'s' * (COUNTS.models != 1)} "
                f"and {COUNTS.query_files} query file{'s' * (COUNTS.query_files != 1)}")
        if COUNTS.rejected:
            line += f"; it rejected {COUNTS.rejected}"
        return line
    if not (skipped or failed):
        return None
    why = locate().reason.splitlines()[0] if locate.cache_info().currsize else ""
    why = re.sub(r" \(looked for .*\)$", "", why.removeprefix(UNAVAILABLE).removeprefix(": "))
    outcome = (f"{skipped} test{'s' * (skipped != 1)} that validate with it skipped" if skipped else
               f"{failed} test{'s' * (failed != 1)} that validate with it failed under {ENV_REQUIRE}=1")
    return f"UPPAAL's parser was not available: {outcome}" + (f" ({why})" if why else "")
