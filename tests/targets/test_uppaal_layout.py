"""rac.targets.uppaal.layout: fresh ids, transitions with their labels stacked, the XML templates."""

from __future__ import annotations

import jinja2
import pytest

from rac.targets.uppaal.layout import Ids, Label, Location, Template, Transition, edge, environment


def test_ids_are_fresh_and_in_order() -> None:
    ids = Ids()
    assert [ids() for _ in range(3)] == ["id0", "id1", "id2"]
    assert Ids()() == "id0"  # each model counts from zero


def test_edge_stacks_its_labels_in_uppaal_order() -> None:
    ids = Ids()
    a, b = Location(ids(), "A", 0, 0), Location(ids(), "B", 100, 40, invariant="t <= 1")
    t = edge(ids, a, b, guard="x > 1", sync="go!", assignment="x = 0", select="i : int[0,2]")
    assert isinstance(t, Transition)
    assert (t.id, t.source, t.target) == ("id2", a.id, b.id)
    assert [label.kind for label in t.labels] == ["select", "guard", "synchronisation", "assignment"]
    assert [label.text for label in t.labels] == ["i : int[0,2]", "x > 1", "go!", "x = 0"]
    # at the midpoint (50, 20), shifted (+6, -8), one line (17) apart
    assert [(label.x, label.y) for label in t.labels] == [(56, 12), (56, 29), (56, 46), (56, 63)]


def test_edge_leaves_out_empty_labels_and_anchors_at_the_middle_nail() -> None:
    ids = Ids()
    a = Location(ids(), "A", 0, 0)
    t = edge(ids, a, a, sync="tick?", nails=[(0, 50), (30, 60), (60, 50)], controllable=True)
    assert t.labels == [Label("synchronisation", "tick?", 36, 52)]
    assert t.nails == [(0, 50), (30, 60), (60, 50)] and t.controllable
    assert edge(ids, a, a, guard="g", anchor=(10, 10)).labels == [Label("guard", "g", 16, 2)]


def test_location_label_offset() -> None:
    location = Location("id0", "Go", 100, 200)
    assert (location.label_x, location.label_y) == (90, 217)


def test_environment_escapes_xml_templates_only_and_refuses_undefined_names() -> None:
    env = environment()
    assert env is environment()
    assert env.autoescape("model.xml.j2") is True and env.autoescape("queries.q.j2") is False
    assert "<location" in env.loader.get_source(env, "model.xml.j2")[0]
    escaped = jinja2.Environment(autoescape=env.autoescape("model.xml.j2")).from_string("{{ t }}")
    assert escaped.render(t="x < 1 && y") == "x &lt; 1 &amp;&amp; y"
    with pytest.raises(jinja2.UndefinedError):
        env.from_string("<a>{{ text }}</a>").render()


def test_template_defaults() -> None:
    template = Template("Timer", "id0", [Location("id0", "Wait", 0, 0)], [])
    assert (template.declaration, template.parameter, template.name_x, template.name_y) == ("", "", 0, 0)
