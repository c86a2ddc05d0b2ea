"""End to end: a generated sum or condition of hundreds of terms (a flat chain of `+`, `&&`, `||`) is no deep
nesting (E0006): ``rac check``, ``rac compile`` (UPPAAL, checked by UPPAAL's parser; Python, stepped against
``rac.load``) and ``rac verify`` take it."""

from __future__ import annotations

import importlib.util
import random
from pathlib import Path

import pytest
from engine_files import write_engine_file

import rac
from rac.cli.main import main

TERMS = 320


CONJUNCTION = " && ".join(["!isClose"] * TERMS)
DISJUNCTION = " || ".join(f"dgoal < {i + 1}" for i in range(TERMS))
BONUS = " + ".join(f"dgoal / {2 ** (i % 3)}" for i in range(TERMS))
SUM = " + ".join(["sa"] * TERMS)
AUTOMATON = f"""\
automaton Long {{
    input isClose : bool
    input dgoal   : real in [0, 500]

    reward sa, pr
    priority sa > pr
    objective 10 * sa + pr

    sample every 1
    horizon 10

    initial location Normal {{ sa' == 1;  pr' == 1 }}
    location Unsafe         {{ sa' == -1; pr' == 0 }}

    edge * -> Unsafe when isClose do sa = sa - 20000
    edge * -> Normal when {CONJUNCTION}

    at end when {DISJUNCTION} do pr += {BONUS} - dgoal

    query Qa: A[] {SUM} <= 100000
}}
"""


def test_check_and_compile_a_file_of_long_chains(tmp_path: Path, capsys: pytest.CaptureFixture[str], utap) -> None:
    path = tmp_path / "long.ra"
    path.write_text(AUTOMATON, encoding="utf-8")
    assert main(["check", str(path)]) == 0
    out = capsys.readouterr().out
    assert "long.ra: ok" in out and "P2 holds for `sa`" in out
    formatted = tmp_path / "formatted.ra"
    formatted.write_text(AUTOMATON, encoding="utf-8")
    assert main(["fmt", str(formatted)]) == 0
    text = formatted.read_text(encoding="utf-8")  # the chains printed back as written: no parentheses added
    assert all(chain in text for chain in (CONJUNCTION, DISJUNCTION, f"{BONUS} - dgoal", SUM)) and "(" not in text

    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "long.xml")]) == 0
    utap.validate_files(tmp_path / "long.xml", tmp_path / "long.q")

    assert main(["compile", "--target", "python", str(path), "-o", str(tmp_path / "long_ra.py")]) == 0
    spec = importlib.util.spec_from_file_location("long_ra", tmp_path / "long_ra.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    generated, loaded = module.Long(), rac.load(path)
    rng = random.Random(1)
    for _ in range(20):
        generated.reset()
        loaded.reset()
        for _step in range(loaded.steps):
            inputs = {"isClose": rng.random() < 0.1, "dgoal": rng.uniform(0, 400)}
            assert generated.step(inputs) == loaded.step(inputs)
        inputs = {"isClose": False, "dgoal": rng.choice([0.5, 150.25, 319.5, 400.0])}
        assert generated.end(inputs) == loaded.end(inputs)
        assert generated.objective == loaded.objective


def test_verify_a_model_with_long_chains(tmp_path: Path, capsys: pytest.CaptureFixture[str], utap) -> None:
    queries = {"AnyV": "E<> " + " || ".join(f"v >= {i / 10:g}" for i in range(TERMS, 0, -1)),
               "Sums": "A[] Close imply " + " + ".join(["sa"] * TERMS) + " <= 0",
               "Stays": "E[] " + " && ".join(["!collide()"] * TERMS)}
    path = write_engine_file(tmp_path, "goal_ahead", queries)
    text = path.read_text(encoding="utf-8")
    binding = "near = mindist() < 3 * collision_distance"
    assert binding in text
    path.write_text(text.replace(binding, "near = " + " + ".join(["mindist()"] * TERMS)
                                 + f" < {TERMS} * 3 * collision_distance"), encoding="utf-8")
    assert main(["compile", "--target", "uppaal", str(path), "-o", str(tmp_path / "model.xml")]) == 0
    utap.validate_files(tmp_path / "model.xml", tmp_path / "model.q")
    assert main(["verify", str(path), "--out", str(tmp_path / "out")]) == 0
    out = capsys.readouterr().out
    assert out.count("-- Formula is satisfied.") == 3
