"""Shared helpers for the tests that run rac as a command (tests/test_cli.py, tests/test_install.py)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import rac

REPOSITORY = Path(__file__).resolve().parent.parent
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

