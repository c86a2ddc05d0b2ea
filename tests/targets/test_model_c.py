"""Differential test: the emitted UPPAAL declarations, compiled as C, against rac.model.native.

The declarations from rac.targets.uppaal.declarations are pasted verbatim after a small C prelude
(the includes and ``#define fint(x) ((int32_t)(x))``) and a ``main`` that reads one state per line
(``x y v acc head jerk turn k``) and prints ``collide() offroad() goal()``, ``mindist()`` and
``dist_goal()`` (as ``%.17e``, read back exactly, and as significands), every obstacle's
``obs_present/obs_x/obs_y`` and ``sense_state()``'s new state. Every number must equal the native
model's bit for bit, on a few hundred seeded random states per scenario plus simulated runs.
"""

from __future__ import annotations

import math
import random
import shutil
import subprocess
from dataclasses import replace
from fractions import Fraction as F
from pathlib import Path

import numpy as np
import pytest
from test_model_native import (
    DIVIDERS,
    across_the_divider,
    crossing_scenario,
    divided_scenario,
    goal_scenario,
    make_spec,
    straight_scenario,
)

from rac.model import ModelData, NativeModel, State, build_model_data
from rac.targets.uppaal.declarations import C_PRELUDE, declared_names, emit_declarations
from rac.targets.uppaal.expr import double_literal

COMPILER = shutil.which("cc") or shutil.which("gcc")
needs_cc = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")

#: The C mains' loop head: one state and its sample per input line, into the model's globals.
READ_STATE = r"""    while (scanf("%lld %lld %lld %lld %lld %lld %lld %lld",
                 &in[0], &in[1], &in[2], &in[3], &in[4], &in[5], &in[6], &in[7]) == 8) {
        x = (int32_t)in[0];
        y = (int32_t)in[1];
        v = (int32_t)in[2];
        acc = (int32_t)in[3];
        head = (int32_t)in[4];
        jerk = (int32_t)in[5];
        turn = (int32_t)in[6];
        count = (int32_t)in[7];
"""

MAIN = r"""
#include <stdio.h>

int main(void) {
    long long in[8];
    int32_t i;
    double md;
    double dg;
""" + READ_STATE + r"""        md = mindist();
        dg = dist_goal();
        printf("%d %d %d %.17e %.17e %lld %lld", (int)collide(), (int)offroad(), (int)goal(), md, dg,
               (long long)(md * SCALE_D), (long long)(dg * SCALE_D));
        for (i = 0; i < OBS_N; i++) {
            printf(" %d %.17e %.17e", (int)obs_present(i), obs_x(i), obs_y(i));
        }
        sense_state();
        printf(" %d %d %d %d %d %d %d\n", (int)x, (int)y, (int)v, (int)acc, (int)head, (int)jerk, (int)turn);
    }
    return 0;
}
"""

def anywhere_scenario():
    """:func:`goal_scenario` with a goal of time alone (no position: ``Goal.anywhere``), 2 to 4.5 s."""
    scenario = goal_scenario()
    return replace(scenario, name="anywhere", goal=replace(scenario.goal, regions=(), anywhere=True))


#: (name, scenario builder, spec)
CASES = [
    ("straight", straight_scenario, make_spec(3)),
    ("crossing", crossing_scenario, make_spec(4, granularity=F(1, 5), decide=F(3, 10))),
    ("goal", goal_scenario, make_spec(2, granularity=F(1, 4), sense=F(1, 5), decide=F(2, 5))),
    ("goal-coarse", goal_scenario, make_spec(1, min_speed=F(-2), max_speed=F(15))),
    ("goal-anywhere", anywhere_scenario, make_spec(2)),
    # the modelling choices: integer increments (each sub-step adds truncated increments) and a
    # start whose off-road state is not checked
    ("straight-increments", straight_scenario, replace(make_spec(3), dynamics="increments", offroad_from=3)),
    ("crossing-increments", crossing_scenario,
     replace(make_spec(2, granularity=F(1, 2), decide=F(3, 10)), dynamics="increments")),
]


def compile_model(data: ModelData, folder: Path, main: str = MAIN) -> Path:
    source = folder / f"{data.name}.c"
    source.write_text(C_PRELUDE + emit_declarations(data) + "\n" + main, encoding="utf-8")
    binary = folder / data.name
    result = subprocess.run([COMPILER, "-O2", "-ffp-contract=off", "-fno-builtin", "-std=c99", "-Wall", "-Werror", "-o",
                             str(binary), str(source), "-lm"], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    return binary


def python_line(model: NativeModel, state: State, k: int) -> str:
    """What the C main prints for one state, computed natively."""
    md = model.mindist(state, k)
    dg = model.dist_goal(state)
    scale = model.scale_d
    parts = [str(int(model.collide(state, k))), str(int(model.offroad(state, k))), str(int(model.goal(state, k))),
             repr(md), repr(dg), str(int(md * scale)), str(int(dg * scale))]
    for i in range(model.data.obstacle_count):
        position = model.obstacle_position(i, k)
        if position is None:
            parts += ["0", "0.0", "0.0"]
        else:
            parts += ["1", repr(position[0]), repr(position[1])]
    parts += [str(n) for n in model.sense(state)]
    return " ".join(parts)


def normalise(line: str) -> str:
    """A C output line with every ``%.17e`` double read back and printed as Python's ``repr``."""
    return " ".join(repr(float(p)) if "e" in p or "n" in p else p for p in line.split())


def random_states(model: NativeModel, rng: random.Random, count: int) -> list[tuple[State, int]]:
    """Realistic states: near the road, speeds in (and a little beyond) the range, headings in [-pi, pi]."""
    data = model.data
    scale = data.scale
    xs = [s / scale for s in data.road_x]
    ys = [s / scale for s in data.road_y]
    low_x, high_x, low_y, high_y = min(xs) - 5, max(xs) + 5, min(ys) - 5, max(ys) + 5
    jerks = data.action("jerk").values
    turns = data.action("turn").values
    horizon = max([data.obs_until[i] for i in range(data.obstacle_count) if data.obs_until[i] < 10**6]
                  + [data.goal_high if data.goal_high < 10**6 else 0, 100]) + 5
    speed_low, speed_high = model.min_speed_d, model.max_speed_d
    ma = model.max_acc_d
    states = []
    for _ in range(count):
        if rng.random() < 0.5 and data.obstacle_count:  # close to an obstacle, to exercise mindist/collide
            i = rng.randrange(data.obstacle_count)
            k = rng.randrange(data.obs_from[i], min(data.obs_until[i], horizon) + 1)
            ox, oy, _ = model.obstacle_position(i, k)
            px, py = ox + rng.uniform(-8, 8), oy + rng.uniform(-4, 4)
        else:
            k = rng.randrange(0, horizon)
            px, py = rng.uniform(low_x, high_x), rng.uniform(low_y, high_y)
        values = (px, py, rng.uniform(speed_low - 1, speed_high + 1), rng.uniform(-ma - 0.5, ma + 0.5),
                  rng.uniform(-math.pi, math.pi))
        state = State(*(int(value * scale) for value in values), rng.choice(jerks), rng.choice(turns))
        states.append((state, k))
    return states


def simulated_states(model: NativeModel, rng: random.Random, runs: int, steps: int) -> list[tuple[State, int]]:
    """States along native runs from the start, with random actions at each decision."""
    data = model.data
    jerks = data.action("jerk").values
    turns = data.action("turn").values
    found = []
    for _ in range(runs):
        state = model.initial_state()
        for k in range(steps):
            if k % data.decide_every == 0:
                state = state._replace(jerk=rng.choice(jerks), turn=rng.choice(turns))
            found.append((state, k))
            state = model.sense(state)
    return found


@needs_cc
@pytest.mark.parametrize(("name", "build", "spec"), CASES, ids=[case[0] for case in CASES])
def test_c_agrees_with_native(name, build, spec, tmp_path):
    data = build_model_data(build(), spec)
    model = NativeModel(data)
    binary = compile_model(data, tmp_path)
    rng = random.Random(f"rac-model-{name}")
    states = random_states(model, rng, 400) + simulated_states(model, rng, runs=4, steps=60)
    stdin = "".join(f"{' '.join(map(str, state))} {k}\n" for state, k in states)
    result = subprocess.run([str(binary)], input=stdin, capture_output=True, text=True, check=True, timeout=60)
    lines = result.stdout.splitlines()
    assert len(lines) == len(states)
    mismatches = [(state, k, line, expected) for (state, k), line in zip(states, lines)
                  if normalise(line) != (expected := python_line(model, state, k))]
    assert not mismatches, f"{len(mismatches)} of {len(states)} states differ; first: {mismatches[0]}"
    # the sample exercised every branch: collisions, off-road states and goal hits both ways
    flags = [tuple(line.split()[:3]) for line in lines]
    assert {f[1] for f in flags} == {"0", "1"}
    if data.obstacle_count:
        assert {f[0] for f in flags} == {"0", "1"}
    if name.startswith("goal"):
        assert "1" in {f[2] for f in flags}
    if data.goal_anywhere:  # the window alone: goal() at every state inside it, and dist_goal() 0
        assert {f[2] for f in flags} == {"0", "1"}
        assert all(f[2] == str(int(data.goal_low <= k <= data.goal_high)) for f, (_, k) in zip(flags, states))
        assert {line.split()[4] for line in lines} == {"0.00000000000000000e+00"}


EXAMPLE = Path(__file__).resolve().parents[2] / "examples" / "left_turn" / "left_turn.xml"


@needs_cc
def test_c_agrees_with_native_on_a_commonroad_scenario(tmp_path):
    from rac.model.commonroad import load_scenario

    data = build_model_data(load_scenario(EXAMPLE), make_spec(3, max_speed=F(15)))
    model = NativeModel(data)
    binary = compile_model(data, tmp_path)
    rng = random.Random("rac-model-left-turn")
    states = random_states(model, rng, 300) + simulated_states(model, rng, runs=3, steps=80)
    stdin = "".join(f"{' '.join(map(str, state))} {k}\n" for state, k in states)
    lines = subprocess.run([str(binary)], input=stdin, capture_output=True, text=True, check=True,
                           timeout=60).stdout.splitlines()
    assert len(lines) == len(states)
    bad = [(state, k) for (state, k), line in zip(states, lines) if normalise(line) != python_line(model, state, k)]
    assert not bad, f"{len(bad)} of {len(states)} states differ; first: {bad[0]}"


@needs_cc
@pytest.mark.parametrize("divider", DIVIDERS)
def test_c_sees_no_gap_along_a_divider_given_twice(tmp_path, divider):
    """The emitted model reads the road the engine reads: a divider that the map gives twice (float
    noise, or sampled at other points along it) is no gap in it at exponent 2, where the old road's
    offroad() held at 198 and 22 of these states (test_a_divider_given_twice_is_no_gap_in_the_road)."""
    scenario = divided_scenario(tmp_path, divider)
    data = build_model_data(scenario, make_spec(2))
    model = NativeModel(data)
    states = across_the_divider(scenario, data)
    binary = compile_model(data, tmp_path)
    stdin = "".join(f"{' '.join(map(str, state))} 0\n" for state in states)
    lines = subprocess.run([str(binary)], input=stdin, capture_output=True, text=True, check=True,
                           timeout=60).stdout.splitlines()
    assert len(lines) == len(states) > 1000
    assert {line.split()[1] for line in lines} == {"0"}  # offroad() nowhere
    bad = [state for state, line in zip(states, lines) if normalise(line) != python_line(model, state, 0)]
    assert not bad, f"{len(bad)} of {len(states)} states differ; first: {bad[0]}"


@needs_cc
def test_declarations_compile_without_obstacles_or_goal(tmp_path):
    scenario = goal_scenario()
    bare = type(scenario)(name="bare", path="bare.xml", dt=0.1, road=scenario.road, obstacles=(),
                          ego=scenario.ego, goal=type(scenario.goal)((), 0.0, math.inf))
    data = build_model_data(bare, make_spec(3))
    assert data.goal_high == 2**31 - 1
    binary = compile_model(data, tmp_path)
    model = NativeModel(data)
    state = model.initial_state()
    result = subprocess.run([str(binary)], input=f"{' '.join(map(str, state))} 7\n", capture_output=True,
                            text=True, check=True)
    assert normalise(result.stdout.strip()) == python_line(model, state, 7)


def test_declarations_are_deterministic_and_uppaal_shaped():
    data = build_model_data(crossing_scenario(), make_spec(4))
    text = emit_declarations(data)
    assert text == emit_declarations(build_model_data(crossing_scenario(), make_spec(4)))
    for needle in ("int32_t count = 0;", "void sense_state()", "double mindist()", "bool collide()", "bool offroad()",
                   "bool goal()", "double dist_goal()", "const double SENSE_UNIT = 0.01;"):
        assert needle in text
    assert " int " not in text and "int[" not in text and "meta" not in text and "&&=" not in text
    assert "[0]" not in text  # no empty arrays
    names = declared_names(data)
    assert names[:2] == ("SCALE", "SCALE_D") and "JERK_VALUES" in names and "count" in names
    assert names[-5:] == ("in_road", "in_goal", "offroad", "goal", "dist_goal")
    assert {"x", "y", "v", "acc", "head", "jerk", "turn", "sense_state", "mindist", "collide", "i2d",
            "d2i"} <= set(names)
    assert len(names) == len(set(names))


def test_double_literals():
    assert double_literal(0.1) == "0.1"
    assert double_literal(1e-05) == "1.0e-5"  # one double_literal for the whole UPPAAL target
    assert double_literal(1e20) == "1.0e20"
    assert double_literal(2.0) == "2.0"
    assert double_literal(-0.5) == "-0.5"
    with pytest.raises(ValueError):
        double_literal(math.inf)


#: Under `collision sticky`: the state of each sample in, keep_collision() as the Controller calls it
#: (at the start, then after sense_state()), collide() out.
STICKY_MAIN = r"""
#include <stdio.h>

int main(void) {
    long long in[8];
""" + READ_STATE + r"""        keep_collision();
        printf("%d\n", (int)collide());
    }
    return 0;
}
"""


@needs_cc
def test_c_keeps_a_sticky_collision_as_the_engine_does(tmp_path):
    """The emitted crashed/keep_collision()/collide() along a run that meets a crossing car and leaves
    it: the engine's sticky labels, sample by sample."""
    from test_modelling_choices import sticky_data

    from rac.engine.simulate import label_runs, simulate

    data = sticky_data()
    runs = simulate(data, runs=1, horizon_samples=40, seed=1,
                    policy=lambda k, states: np.eye(3, dtype=bool)[[1]])
    binary = compile_model(data, tmp_path, STICKY_MAIN)
    stdin = "".join(f"{' '.join(map(str, runs.states[0, k].tolist()))} {k}\n" for k in range(41))
    out = subprocess.run([str(binary)], input=stdin, capture_output=True, text=True, check=True, timeout=60)
    c_labels = [line == "1" for line in out.stdout.split()]
    engine = label_runs(data, runs, "collide")[0].tolist()
    assert c_labels == engine
    assert any(engine) and engine[-1]  # a collision, remembered to the end

