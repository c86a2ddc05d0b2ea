"""Every option of every ``rac`` sub-command is documented: one of its spellings (``-q`` or ``--quiet``)
appears in docs/*.md or the README. ``rac experiment --combination`` was in ``--help`` only."""

from __future__ import annotations

import argparse
import re
from pathlib import Path

from rac.cli.arguments import build_parser

ROOT = Path(__file__).resolve().parents[2]


def _documented_text() -> str:
    pages = sorted((ROOT / "docs").glob("*.md"))
    return "\n".join(page.read_text(encoding="utf-8") for page in [*pages, ROOT / "README.md"])


def test_every_option_is_documented() -> None:
    text = _documented_text()
    commands = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for name, parser in commands.choices.items():
        for action in parser._actions:
            spellings = [s for s in action.option_strings if s not in ("-h", "--help")]
            if spellings and not any(re.search(rf"(?<![\w-]){re.escape(s)}(?![\w-])", text) for s in spellings):
                missing.append(f"rac {name} {'/'.join(spellings)}")
    assert not missing, f"options in --help but in no page of docs/ nor the README: {missing}"


def test_every_verdict_method_is_documented() -> None:
    """``rac verify``'s JSON ``method`` can take every value of ``METHODS``; docs/verify.md named four of them
    (``on demand``, ``product search``, ``strategy run``, ... were in the output only)."""
    from rac.verify.status import METHODS

    text = (ROOT / "docs" / "verify.md").read_text(encoding="utf-8")
    paragraph = text[text.index("**How a verdict was reached**"):]
    paragraph = paragraph[:paragraph.index("\n\n")]
    missing = [method for method in METHODS if f"`{method}`" not in paragraph]
    assert not missing, f"methods rac verify reports that docs/verify.md does not explain: {missing}"
