"""The process templates of the automaton-alone UPPAAL model: ``Timer``, ``Environment`` and the
reward automaton (what each does: :mod:`rac.targets.uppaal.automaton`), with their layout.

:class:`Processes` builds their locations and transitions; the text of the reward automaton's
labels comes from :class:`rac.targets.uppaal.labels.Labels`. The whole model
(:mod:`rac.targets.uppaal.model`) reuses the reward automaton's template and adds its own processes.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.runtime.semantics import first_sample_reads
from rac.targets.uppaal.labels import Labels
from rac.targets.uppaal.layout import Ids, Location, Template, Transition, edge
from rac.targets.uppaal.names import Names
from rac.targets.uppaal.significands import Accrual, NumericInput

__all__ = ["Processes"]


@dataclass
class Processes:
    """The templates of the model of the automaton ``a``. ``n`` are its UPPAAL names, ``process`` the
    reward automaton's; ``g`` the fresh names the target adds (``g["timer"]``, ``g["wait"]``,
    ``g["count"]``, ...), ``channels`` the broadcast channels by role, ``select`` each input's select
    variable, ``labels`` the text of the reward automaton's labels."""

    a: ir.Automaton
    n: Names
    process: str
    g: dict[str, str]
    channels: dict[str, str]
    select: dict[str, str]
    labels: Labels

    def ending(self) -> tuple[str, str, str]:
        """What ``episode ends when COND`` adds to the Timer's ``sense!`` edges (all "" without it): to the
        guard of those that go on ``&& !(COND)``, to the one into the ending ``|| (COND)`` (the sample's
        inputs end the run: ``finish!`` follows), and to its assignment ``, ended = true``. COND reads the
        inputs only, which the ``sense?`` edges do not change, so the sender's guard sees what they see."""
        ends = self.a.ending
        if ends is None:
            return "", "", ""
        condition = self.labels.guard(ends) or "true"
        return f" && !({condition})", f" || ({condition})", f", {self.g['ended']} = true"

    def timer(self, ids: Ids) -> Template:
        """``accrue!`` every period, waits for ``read?``, then ``sense!``; ``finish!`` after the last sample
        (and after a sample whose inputs satisfy ``episode ends when``: :meth:`ending`)."""
        g, ch = self.g, self.channels
        goes_on, last, finish = self.ending()
        wait = Location(ids(), g["wait"], 0, 0, f"{g['t']} <= {g['period']}")
        accrued = Location(ids(), g["accrued"], 272, 0, committed=True)
        reading = Location(ids(), g["reading"], 272, 170, committed=True)
        ending = Location(ids(), g["ending"], 544, 170, committed=True)
        done = Location(ids(), g["done"], 816, 170, f"{g['t']} <= {g['period']}")
        transitions = [
            edge(ids, wait, accrued, guard=f"{g['t']} >= {g['period']} && {g['count']} < {g['steps']}",
                  sync=f"{ch['accrue']}!", assignment=f"{g['t']} = 0, {g['count']}++", anchor=(40, -60)),
            edge(ids, accrued, reading, sync=f"{ch['read']}?", assignment=f"{g['settled']} = false",
                  anchor=(282, 70)),
            edge(ids, reading, wait, guard=f"{g['count']} < {g['steps']}{goes_on}", sync=f"{ch['sense']}!",
                  assignment=f"{g['settled']} = true", nails=[(0, 170)], anchor=(40, 180)),
            edge(ids, reading, ending, guard=f"{g['count']} == {g['steps']}{last}", sync=f"{ch['sense']}!",
                  assignment=f"{g['settled']} = true{finish}", anchor=(330, 180)),
            edge(ids, ending, done, sync=f"{ch['finish']}!", anchor=(620, 180)),
            edge(ids, done, done, guard=f"{g['t']} >= {g['period']}", assignment=f"{g['t']} = 0",
                  nails=[(790, 240), (842, 240)], anchor=(780, 250)),
        ]
        return Template(g["timer"], wait.id, [wait, accrued, reading, ending, done], transitions,
                         declaration=f"clock {g['t']};", name_x=-40, name_y=-100)

    def environment(self, ids: Ids, inputs: list[NumericInput]) -> Template:
        """On ``accrue?`` it chooses every input (``select``, guarded by ``assume``) and sends ``read!``."""
        g, ch, a = self.g, self.channels, self.a
        idle = Location(ids(), g["idle"], 0, 0)
        choosing = Location(ids(), g["choosing"], 340, 0, committed=True)
        selects, assigns, names = [], [], {}
        numeric = {i.source: i for i in inputs}
        for item in a.inputs:
            var = self.select[item.name]
            if item.is_bool:
                selects.append(f"{var} : int[0,1]")
                assigns.append(f"{self.n[item.name]} = {var}")
                names[item.name] = var
            else:
                data = numeric[item.name]
                selects.append(f"{var} : int[0,{max(data.count - 1, 0)}]")
                assigns.append(f"{self.n[item.name]} = {data.array}[{var}]")
                names[item.name] = f"{data.array}[{var}]"
        transitions = [
            edge(ids, idle, choosing, sync=f"{ch['accrue']}?", nails=[(170, -50)], anchor=(140, -80)),
            edge(ids, choosing, idle, select=", ".join(selects), guard=self.labels.guard(a.assume, names),
                  sync=f"{ch['read']}!", assignment=", ".join(assigns), nails=[(170, 60)], anchor=(20, 80)),
        ]
        return Template(g["environment"], idle.id, [idle, choosing], transitions, name_x=-40, name_y=-100)

    def automaton(self, ids: Ids, unit: Fraction, accruals: list[list[Accrual | None]]) -> Template:
        """The reward automaton: its locations on a circle, one ``sense?`` transition per ``.ra`` edge,
        the ``accrue?`` self-loops of the mirrors and the ``finish?`` self-loops of the end clauses."""
        a, g, ch, labels = self.a, self.g, self.channels, self.labels
        count = len(a.locations)
        radius = max(200, 70 * count)
        locations = []
        for i, location in enumerate(a.locations):
            angle = -math.pi / 2 + 2 * math.pi * i / count
            x, y = round(radius * math.cos(angle)), round(radius * math.sin(angle))
            if count == 1:
                x, y = 0, 0
            locations.append(Location(ids(), self.n[location.name], x, y, labels.ode(location, unit, g.get("ended"))))
        # Rates that read inputs: the first sample's accrual uses that sample's inputs (nothing is held yet),
        # so it happens on read? at the first sample instead of on accrue?.
        first_reads = first_sample_reads(a)
        loops: list[list[dict]] = [[] for _ in a.locations]
        edges: list[tuple[int, int, dict]] = []
        for i, row in enumerate(accruals):
            parts = labels.accrual(row)
            if parts:
                loops[i].append({"guard": f"{g['count']} > 0" if first_reads else "",
                                 "sync": f"{ch['accrue']}?", "assignment": ", ".join(parts)})
            if first_reads and i == a.initial:
                corrections = labels.first_sample(a.locations[i])
                loops[i].append({"guard": f"{g['count']} == 1", "sync": f"{ch['read']}?",
                                 "assignment": ", ".join(parts + corrections)})
        for ra_edge in a.all_edges():
            label = {"guard": labels.guard(ra_edge.guard, span=ra_edge.span), "sync": f"{ch['sense']}?",
                     "assignment": labels.updates(ra_edge.updates, ra_edge.span)}
            if ra_edge.source == ra_edge.target:
                loops[ra_edge.source].append(label)
            else:
                edges.append((ra_edge.source, ra_edge.target, label))
        if a.end_clauses:
            guard, assignment = labels.end_updates()
            for i in range(count):
                loops[i].append({"guard": guard, "sync": f"{ch['finish']}?", "assignment": assignment})
        transitions = []
        for source, target, label in edges:
            transitions.append(_straight(ids, locations[source], locations[target], label))
        for i, labels_of in enumerate(loops):
            transitions += _loops(ids, locations[i], labels_of, count)
        by_id = {t.id: t for t in transitions}
        ordered = sorted(by_id, key=lambda k: int(k[2:]))
        return Template(self.process, locations[a.initial].id, locations, [by_id[k] for k in ordered],
                         name_x=-radius - 100, name_y=-radius - 100)


def _straight(ids: Ids, source: Location, target: Location, label: dict) -> Transition:
    """An edge between two locations, bent a little to its right so that A→B and B→A stay apart."""
    dx, dy = target.x - source.x, target.y - source.y
    length = math.hypot(dx, dy) or 1.0
    nx, ny = dy / length, -dx / length
    bend = 40
    nail = (round((source.x + target.x) / 2 + nx * bend), round((source.y + target.y) / 2 + ny * bend))
    return edge(ids, source, target, nails=[nail], anchor=nail, **label)


def _loops(ids: Ids, location: Location, labels: list[dict], count: int) -> list[Transition]:
    """Self-loops fanned out away from the centre of the circle of locations."""
    direction = math.atan2(location.y, location.x) if (location.x or location.y) and count > 1 else -math.pi / 2
    spread = math.radians(50)
    result = []
    for j, label in enumerate(labels):
        angle = direction + (j - (len(labels) - 1) / 2) * spread
        nails = []
        for side in (-1, 1):
            phi = angle + side * math.radians(15)
            nails.append((round(location.x + 80 * math.cos(phi)), round(location.y + 80 * math.sin(phi))))
        anchor = (round(location.x + 95 * math.cos(angle)), round(location.y + 95 * math.sin(angle)))
        if math.cos(angle) < -0.3:
            anchor = (anchor[0] - 170, anchor[1])
        result.append(edge(ids, location, location, nails=nails, anchor=anchor, **label))
    return result
