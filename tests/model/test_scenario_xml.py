"""rac.model.scenario_xml: generated vehicles on exact values, and byte-stable, schema-checked XML."""

from __future__ import annotations

import math

import numpy as np
import pytest
from lxml import etree

from rac.model.scenario_xml import (
    DECIMALS,
    DT,
    FILE_DATE,
    canonical_xml,
    check_schema,
    clean,
    recorded_car,
    straight_car,
)
from rac.model.scenes import scene_bytes


def test_clean_rounds_to_the_file_precision_and_drops_negative_zero() -> None:
    assert DECIMALS == 6
    assert clean(1.23456789) == pytest.approx(1.234568, abs=0)
    value = clean(-1e-9)
    assert value == 0.0 and math.copysign(1.0, float(value)) == 1.0
    assert clean(np.array([0.1234564, -0.0])).tolist() == [0.123456, 0.0]


def test_straight_car_drives_at_constant_velocity() -> None:
    car = straight_car(7, 10.0, 2.0, math.pi / 2, 5.0, steps=4)
    assert car.obstacle_id == 7
    states = car.prediction.trajectory.state_list
    assert [s.time_step for s in states] == [1, 2, 3, 4]
    heading = float(clean(math.pi / 2))  # the heading as the file holds it drives the positions
    for state in states:
        assert state.orientation == heading == 1.570796
        distance = 5.0 * state.time_step * DT
        expected = clean(np.array([10.0 + math.cos(heading) * distance, 2.0 + math.sin(heading) * distance]))
        assert np.array_equal(state.position, expected)
        assert state.velocity == 5.0
    assert np.array_equal(car.initial_state.position, [10.0, 2.0])


def test_recorded_car_follows_its_track() -> None:
    def track(t: float) -> tuple[float, float, float, float]:
        return 3.0 * t, 1.0, 0.0, 3.0

    car = recorded_car(9, track, steps=3, length=5.0)
    positions = [car.initial_state.position.tolist(),
                 *(s.position.tolist() for s in car.prediction.trajectory.state_list)]
    assert positions == [[0.0, 1.0], [0.3, 1.0], [0.6, 1.0], [0.9, 1.0]]
    assert car.obstacle_shape.length == 5.0


def test_generated_scene_is_canonical_and_valid() -> None:
    data = scene_bytes("highway")
    root = etree.fromstring(data)
    assert root.get("date") == FILE_DATE
    tags = [child.tag for child in root.find("scenarioTags")]
    assert tags == sorted(tags)
    assert canonical_xml(data) == data  # canonical already: a fixed point
    check_schema(data)


def test_canonical_xml_pins_the_date_and_sorts_sets() -> None:
    root = etree.fromstring(scene_bytes("highway"))
    root.set("date", "1999-12-31")
    tags = root.find("scenarioTags")
    tags[:] = list(reversed(list(tags)))
    shuffled = etree.tostring(root, xml_declaration=True, encoding="UTF-8")
    assert canonical_xml(shuffled) == scene_bytes("highway")


def test_check_schema_refuses_an_invalid_file() -> None:
    with pytest.raises(RuntimeError, match="does not match"):
        check_schema(b"<commonRoad><lanelet id='1'/></commonRoad>")
