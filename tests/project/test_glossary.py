"""Terms are defined where a page first uses them: the paragraph of a page's first use of a
glossary term links to its entry in docs/glossary.md (the issue: C1, C2, TD, "significand" and
"product" were used before anything said what they are)."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
GLOSSARY = REPO / "docs" / "glossary.md"
PAGES = [REPO / "README.md", *sorted(p for p in (REPO / "docs").glob("*.md") if p != GLOSSARY)]
#: term -> (how a page writes it, its anchor in docs/glossary.md)
TERMS = {
    "C1": (r"\bC1\b", "c1"),
    "C2": (r"\bC2\b", "c2"),
    "TD": (r"\bTD\b", "td"),
    "significand": (r"\bsignificands?\b", "significand"),
    # the product of model and automaton, not arithmetic's ("the product of 2 per boolean input")
    "product": (r"\bproduct\b(?=( of model| with| semantics|'s state|;| \(with))|\bengine's product\b", "product"),
}


#: A markdown link: its text stays, its target goes.
_LINK = re.compile(r"\[([^\]]*)\]\([^)]*\)")


def paragraphs(page: Path) -> list[str]:
    """The page's prose paragraphs, in order, without code blocks and HTML comments."""
    text = re.sub(r"^\s*```.*?^\s*```", "", page.read_text(encoding="utf-8"), flags=re.S | re.M)
    text = re.sub(r"<!--.*?-->", "", text, flags=re.S)
    return [p for p in re.split(r"\n\s*\n", text) if p.strip() and not p.lstrip().startswith("#")]  # not headings


def test_the_glossary_has_each_anchor() -> None:
    text = GLOSSARY.read_text(encoding="utf-8")
    for _, anchor in TERMS.values():
        assert f'<a id="{anchor}"></a>' in text, anchor


@pytest.mark.parametrize("page", PAGES, ids=lambda p: str(p.relative_to(REPO)))
def test_first_use_links_the_glossary(page: Path) -> None:
    missing = []
    link = "glossary.md" if page.parent.name == "docs" else "docs/glossary.md"
    for term, (pattern, anchor) in TERMS.items():
        # a use inside link text counts, its target does not (`[numbers](#numbers-significands-and-mirrors)`)
        first = next((p for p in paragraphs(page) if re.search(pattern, _LINK.sub(r"\1", p))), None)
        if first is not None and f"{link}#{anchor}" not in first:
            missing.append(f"{term}: {first.strip()[:100]!r}")
    assert not missing, f"{page.name}: first use without a link to its glossary entry:\n" + "\n".join(missing)
