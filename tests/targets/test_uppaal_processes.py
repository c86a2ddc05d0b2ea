"""rac.targets.uppaal.processes: the Timer, Environment and reward automaton templates."""

from __future__ import annotations

from test_uppaal_significands import generator

from rac.targets.uppaal.layout import Ids, Template
from rac.targets.uppaal.processes import Processes


def texts(template: Template) -> list[list[str]]:
    return [[label.text for label in t.labels] for t in template.transitions]


def test_timer_accrues_reads_senses_and_finishes() -> None:
    processes: Processes = generator().processes
    timer = processes.timer(Ids())
    assert timer.name == "Timer"
    assert [loc.name for loc in timer.locations] == ["Wait", "Accrued", "Reading", "Ending", "Done"]
    syncs = [label.text for t in timer.transitions for label in t.labels if label.kind == "synchronisation"]
    assert syncs == ["accrue!", "read?", "sense!", "sense!", "finish!"]
    by_id = {loc.id: loc.name for loc in timer.locations}
    assert by_id[timer.init] == "Wait"
    assert all(t.source in by_id and t.target in by_id for t in timer.transitions)


def test_environment_chooses_every_input_on_read() -> None:
    g = generator()
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    env = g.processes.environment(Ids(), inputs)
    assert [loc.name for loc in env.locations] == ["Idle", "Choosing"]
    assert texts(env) == [["accrue?"],
                          ["near_v : int[0,1], d_i : int[0,4]", "read!", "near = near_v, d = d_values[d_i]"]]


def test_reward_automaton_has_its_locations_edges_and_accrual_loops() -> None:
    g = generator()
    inputs = g.numbers.inputs(g.n, g.array, g.select)
    accruals = g.numbers.accruals(inputs, g.n)
    template = g.processes.automaton(Ids(), g._time_unit(), accruals)
    names = {loc.id: loc.name for loc in template.locations}
    assert template.name == "Tiny" and names[template.init] == "Go"
    assert sorted(names.values()) == ["Go", "Slow"]
    assert ["near || d < 25000", "sense?", "sa = sa - 3, iSa = iSa - 30000"] in texts(template)
    assert ["!near && d >= 25000", "sense?"] in texts(template)
    loops = [(names[t.source], [label.text for label in t.labels]) for t in template.transitions
             if t.source == t.target and any(label.text == "accrue?" for label in t.labels)]
    assert sorted(loops) == [("Go", ["accrue?", "iSa = iSa + 5000, iPr = iPr + 10000"]),
                             ("Slow", ["accrue?", "iSa = iSa - 5000"])]
