"""Compare generated text with committed golden files (``RAC_UPDATE_GOLDEN=1`` rewrites them)."""

from __future__ import annotations

import os
from pathlib import Path


def assert_golden(files: dict[Path, str], regenerate: str) -> None:
    """Each path's committed text must equal the generated text; ``regenerate`` says how to update."""
    if os.environ.get("RAC_UPDATE_GOLDEN"):
        for path, text in files.items():
            path.write_text(text, encoding="utf-8")
    for path, text in files.items():
        assert path.exists(), f"{path} is missing; {regenerate}"
        assert text == path.read_text(encoding="utf-8"), f"the output differs from {path}; if intended, {regenerate}"
