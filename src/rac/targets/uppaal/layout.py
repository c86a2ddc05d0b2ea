"""The emitted model's layout: templates, locations, transitions and their labels, and the jinja2
templates of the XML skeleton (autoescaped).

Coordinates are for UPPAAL's editor only (its verifier never reads them).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from importlib import resources

import jinja2

__all__ = ["Ids", "Label", "Location", "Template", "Transition", "edge", "environment"]


@dataclass
class Location:
    id: str
    name: str
    x: int
    y: int
    invariant: str = ""
    committed: bool = False

    @property
    def label_x(self) -> int:
        return self.x - 10

    @property
    def label_y(self) -> int:
        return self.y + 17


@dataclass
class Label:
    kind: str
    text: str
    x: int
    y: int


@dataclass
class Transition:
    id: str
    source: str
    target: str
    labels: list[Label] = field(default_factory=list)
    nails: list[tuple[int, int]] = field(default_factory=list)
    controllable: bool = False


@dataclass
class Template:
    name: str
    init: str
    locations: list[Location]
    transitions: list[Transition]
    declaration: str = ""
    name_x: int = 0
    name_y: int = 0
    parameter: str = ""


class Ids:
    def __init__(self) -> None:
        self.count = 0

    def __call__(self) -> str:
        self.count += 1
        return f"id{self.count - 1}"


def edge(ids: Ids, source: Location, target: Location, *, select: str = "", guard: str = "", sync: str = "",
          assignment: str = "", nails: list[tuple[int, int]] | None = None,
          anchor: tuple[int, int] | None = None, controllable: bool = False) -> Transition:
    """A transition with its labels stacked at ``anchor`` (default: the midpoint or first nail)."""
    nails = nails or []
    if anchor is None:
        if nails:
            anchor = nails[len(nails) // 2]
        else:
            anchor = ((source.x + target.x) // 2, (source.y + target.y) // 2)
    x, y = anchor[0] + 6, anchor[1] - 8
    labels = []
    for kind, text in (("select", select), ("guard", guard), ("synchronisation", sync), ("assignment", assignment)):
        if text:
            labels.append(Label(kind, text, x, y))
            y += 17
    return Transition(ids(), source.id, target.id, labels, nails, controllable)


@lru_cache(maxsize=1)
def environment() -> jinja2.Environment:
    """The jinja2 environment of the UPPAAL templates (XML autoescaped, undefined names an error)."""
    folder = resources.files("rac.targets.uppaal") / "templates"

    def load(name: str) -> str:
        return (folder / name).read_text(encoding="utf-8")

    return jinja2.Environment(
        loader=jinja2.FunctionLoader(load), autoescape=lambda name: bool(name and name.endswith(".xml.j2")),
        trim_blocks=True, lstrip_blocks=True, keep_trailing_newline=True, undefined=jinja2.StrictUndefined)
