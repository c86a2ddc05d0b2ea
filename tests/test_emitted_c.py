"""The emitted whole model, compiled as C, against the engine: one model, one meaning.

The global declarations of the model that ``rac compile --target uppaal`` writes for a file with a
``model`` block are in the subset that is valid both in UPPAAL and in C (tests/test_model_c.py checks
the scenario part against :mod:`rac.model.native`). This test compiles the whole declaration
section (channels, which C has no use for, left out; clocks as doubles), plays the Controller —
``keep_sample()`` on the previous sample's state, then ``read_inputs()`` on the current one — and
compares every input with the value the engine's product (:mod:`rac.engine.product`) gives.
"""

from __future__ import annotations

import html
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

from rac.compiler import compile_text
from rac.engine.expr import Evaluator, Frame
from rac.engine.product import _Bindings
from rac.scenarios.tiny import avoidable_obstacle
from rac.targets.uppaal_functions import C_PRELUDE
from rac.targets.uppaal_model import generate_uppaal_model

COMPILER = shutil.which("cc") or shutil.which("gcc")
needs_cc = pytest.mark.skipif(COMPILER is None, reason="no C compiler (cc or gcc) on PATH")

#: Bindings that read settings the model holds as significands (``length`` at exponent 4 is
#: 4.5555, not 4.55555), ``time``, ``prev`` of a number and of a condition, and model functions.
SETTINGS_AUTOMATON = """\
automaton Reader {{
    input near  : bool
    input gain  : bool
    input d     : real in [0, 1000]
    input len10 : real in [0, 1000]
    input late  : bool
    reward r
    objective r
    sample every 0.5
    horizon 4
    initial location A {{ r' == 1 }}
    location B {{ r' == 0 }}
    edge A -> B when near || late
    edge B -> A when !near && gain && d < 20 && len10 > 1
    model {{
        scenario "{scenario}"
        length 4.55555
        exponent 4
        decide_period 1
        granularity 0.25
        action jerk in [-2, 2] step 2
        action turn in [-0.2, 0.2] step 0.2
        bind near  = mindist() < 3 * collision_distance
        bind gain  = v > prev(v) || prev(acc > 0)
        bind d     = dist_goal()
        bind len10 = length * 10
        bind late  = time > 2.5 && fabs(turn) < comfort_turn * max_turn
    }}
}}
"""

MAIN = r"""
#include <stdio.h>

int main(void) {
    long long in[16];
    while (scanf("%lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld %lld",
                 &in[0], &in[1], &in[2], &in[3], &in[4], &in[5], &in[6], &in[7],
                 &in[8], &in[9], &in[10], &in[11], &in[12], &in[13], &in[14], &in[15]) == 16) {
        x = (int32_t)in[0]; y = (int32_t)in[1]; v = (int32_t)in[2]; acc = (int32_t)in[3];
        head = (int32_t)in[4]; jerk = (int32_t)in[5]; turn = (int32_t)in[6]; count = (int32_t)in[7];
        KEEP_SAMPLE
        x = (int32_t)in[8]; y = (int32_t)in[9]; v = (int32_t)in[10]; acc = (int32_t)in[11];
        head = (int32_t)in[12]; jerk = (int32_t)in[13]; turn = (int32_t)in[14]; count = (int32_t)in[15];
        READ_INPUTS();
        PRINT_INPUTS();
    }
    return 0;
}
"""


def _declaration(xml: str) -> str:
    """The global declaration section, as text."""
    return html.unescape(re.search(r"<declaration>(.*?)</declaration>", xml, re.DOTALL).group(1))


def _as_c(declaration: str) -> str:
    """UPPAAL declarations as C: channels dropped, clocks and hybrid clocks as doubles."""
    lines = []
    for line in declaration.splitlines():
        if re.match(r"\s*(urgent\s+)?(broadcast\s+)?chan\b", line):
            continue
        line = re.sub(r"^(\s*)(hybrid\s+)?clock\b", r"\1double", line)
        lines.append(line)
    return "\n".join(lines)


def compile_reader(xml: str, automaton, folder: Path) -> Path:
    """A C program: per line, a previous and a current state; it prints every input after reading."""
    declaration = _declaration(xml)
    inputs = [item.name for item in automaton.inputs]
    functions = re.findall(r"^void (\w+)\(\)", declaration, re.MULTILINE)
    keep = [f"{f}();" for f in functions if f.startswith("keep_sample")]
    read = next(f for f in functions if f.startswith("read_inputs"))
    prints = " ".join(f'printf("%lld ", (long long){name});' for name in inputs) + ' printf("\\n");'
    main = (MAIN.replace("KEEP_SAMPLE", " ".join(keep)).replace("READ_INPUTS", read)
            .replace("PRINT_INPUTS();", prints))
    source = folder / "reader.c"
    source.write_text(C_PRELUDE + _as_c(declaration) + "\n" + main, encoding="utf-8")
    binary = folder / "reader"
    result = subprocess.run([COMPILER, "-O2", "-ffp-contract=off", "-fno-builtin", "-std=c99", "-o", str(binary),
                             str(source), "-lm"], capture_output=True, text=True, check=False)
    assert result.returncode == 0, result.stderr
    return binary


def random_pairs(data, rng: np.random.Generator, n: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` (previous ego, current ego, k) triples near the road, with actions from the grid."""
    start = np.asarray([data.ego_x, data.ego_y, data.ego_v, data.ego_acc, data.ego_head, 0, 0],
                       dtype=np.int64)
    scale = data.scale
    jerks, turns = np.asarray(data.action("jerk").values), np.asarray(data.action("turn").values)

    def states() -> np.ndarray:
        ego = np.tile(start, (n, 1))
        ego[:, 0] += rng.integers(-5 * scale, 60 * scale, n)
        ego[:, 1] += rng.integers(-3 * scale, 3 * scale, n)
        ego[:, 2] = rng.integers(0, 12 * scale, n)
        ego[:, 3] = rng.integers(-3 * scale, 3 * scale, n)
        ego[:, 4] = rng.integers(-scale // 2, scale // 2, n)
        ego[:, 5] = rng.choice(jerks, n)
        ego[:, 6] = rng.choice(turns, n)
        return ego

    k = rng.integers(1, 9, n)
    return states(), states(), k


@needs_cc
def test_bindings_of_the_emitted_model_are_the_engines(tmp_path: Path) -> None:
    tiny = avoidable_obstacle()
    scenario = tiny.write(tmp_path)
    result = compile_text(SETTINGS_AUTOMATON.format(scenario=scenario.name), str(tmp_path / "reader.ra"))
    automaton = result.raise_for_errors()
    data = result.model_data
    model = generate_uppaal_model(automaton, data=data)
    binary = compile_reader(model.xml, automaton, tmp_path)
    rng = np.random.default_rng(7)
    before, now, k = random_pairs(data, rng, 400)
    lines = "".join(" ".join(map(str, [*b, kk - 1, *c, kk])) + "\n" for b, c, kk in zip(before, now, k))
    out = subprocess.run([str(binary)], input=lines, capture_output=True, text=True, check=True, timeout=60)
    emitted = np.asarray([[int(v) for v in line.split()] for line in out.stdout.splitlines()], dtype=np.int64)
    frame = Frame(k=k, ego=now, prev=Frame(k=k - 1, ego=before))
    engine = _Bindings(Evaluator(data, automaton), automaton).read(frame)
    names = [item.name for item in automaton.inputs]
    for column, name in enumerate(names):
        differ = np.flatnonzero(emitted[:, column] != engine[:, column])
        assert differ.size == 0, (f"input `{name}`: the emitted model reads {emitted[differ[0], column]}, the engine "
                                  f"{engine[differ[0], column]} (state {now[differ[0]].tolist()}, k={k[differ[0]]}); "
                                  f"{differ.size} of {len(k)} states differ")
    # the sample exercised both outcomes of every condition
    for column, item in enumerate(automaton.inputs):
        if item.is_bool:
            assert set(engine[:, column]) == {0, 1}, item.name
