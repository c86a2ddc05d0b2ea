"""Shared helpers for the tests that run rac as a command (tests/cli/test_cli.py,
tests/project/test_install.py), and the ``utap`` fixture: UPPAAL's own parser (tests/support/utap.py),
with a count of its validations printed at the end of the session.

The tests live by package, ``tests/<package>/test_*.py`` for ``src/rac/<package>/`` (``project/``:
the repository as a whole; ``benchmarks/``: the benchmark scripts; the compiler's stages in
``check/``), and import their shared helpers from ``tests/support/`` and this file: these folders
and the packages' are put on the import path here, before any test module is collected (test
module names stay unique across the folders)."""

from __future__ import annotations

import dataclasses
import os
import subprocess
import sys
from pathlib import Path
from typing import Any

import pytest

_HERE = Path(__file__).resolve().parent
# tests/ (this file), tests/support/ (the helpers) and every package's folder: some test modules
# import another's builders (`from test_explore import tiny_data`), as when all lay in tests/
sys.path[:0] = [str(_HERE), str(_HERE / "support"),
                *sorted(str(folder) for folder in _HERE.iterdir() if folder.is_dir() and any(folder.glob("test_*.py")))]

import utap as utap_module  # noqa: E402 - tests/support is on the path from the lines above

import rac  # noqa: E402

REPOSITORY = Path(__file__).resolve().parent.parent
# Off a terminal rac prints a progress line every RAC_PROGRESS_INTERVAL seconds; tests that compare
# stderr must not depend on how fast the machine is (tests/output/test_progress_lines.py sets its own).
os.environ.setdefault("RAC_PROGRESS_INTERVAL", "3600")
#: The folder holding the `rac` package these tests import (src/ in a checkout, site-packages when installed).
RAC_PARENT = Path(rac.__file__).resolve().parent.parent


def rac_env() -> dict[str, str]:
    """The environment for a child Python that must import the same rac as this test process."""
    paths = [str(RAC_PARENT), *filter(None, os.environ.get("PYTHONPATH", "").split(os.pathsep))]
    return {**os.environ, "PYTHONPATH": os.pathsep.join(paths), "PYTHONIOENCODING": "utf-8"}


def run_rac(*args: str | Path, cwd: Path | None = None, timeout: float = 120) -> subprocess.CompletedProcess[str]:
    """``python -m rac ARGS`` in a child process; output captured as text."""
    return subprocess.run([sys.executable, "-m", "rac", *map(str, args)], cwd=cwd, env=rac_env(),
                          capture_output=True, text=True, timeout=timeout, check=False)


# ---------------------------------------------------------------- UPPAAL's parser (tests/support/utap.py)
@pytest.fixture(scope="session")
def utap(tmp_path_factory: pytest.TempPathFactory) -> utap_module.Utap:
    """``utap.validate(xml, queries, name)`` asserts that UPPAAL's parser accepts the model and its
    queries. Skips when the validator is unavailable (fails instead under ``RAC_REQUIRE_UTAP=1``)."""
    try:
        located = utap_module.locate()
    except RuntimeError as exc:  # RAC_UTAP_VALIDATE names no executable
        located = utap_module.Located(None, str(exc))
        misconfigured = True
    else:
        misconfigured = False
    if misconfigured:
        pytest.fail(located.reason, pytrace=False)
    if located.path is None:
        utap_module.unavailable(located.reason)
    return utap_module.Utap(located.path, tmp_path_factory.mktemp("utap"))


def pytest_sessionfinish(session: pytest.Session) -> None:
    """Under pytest-xdist a worker hands its validation counts to the controller, which prints them."""
    workeroutput = getattr(session.config, "workeroutput", None)
    if workeroutput is not None:
        workeroutput["utap_counts"] = dataclasses.asdict(utap_module.COUNTS)


@pytest.hookimpl(optionalhook=True)  # pytest-xdist's hook: the controller hears of each worker ending
def pytest_testnodedown(node: Any, error: object) -> None:
    utap_module.add_counts(getattr(node, "workeroutput", {}).get("utap_counts", {}))


def pytest_terminal_summary(terminalreporter: pytest.TerminalReporter) -> None:
    """One line: how many models and query files UPPAAL's parser accepted (also under ``-q``)."""
    def unavailable(kind: str) -> int:
        return sum(1 for report in terminalreporter.stats.get(kind, ())
                   if utap_module.UNAVAILABLE in str(getattr(report, "longrepr", "")))

    line = utap_module.summary_line(unavailable("skipped"), unavailable("error") + unavailable("failed"))
    if line:
        terminalreporter.write_line(line)
