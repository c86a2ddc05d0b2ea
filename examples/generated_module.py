"""Compile stdlib/driving.ra to a standalone Python module and use the generated class.

The same as running, in a shell::

    rac compile --target python stdlib/driving.ra -o driving_ra.py

The generated ``driving_ra.py`` imports nothing but the standard library, so it can be copied
into a training code base that does not install rac. Its class ``Driving`` has the API of
``rac.load(...)``: ``reset()``, ``step(inputs)``, ``end(inputs)``, ``location``, ``rewards``,
``objective``. This script drives both through one scripted 30 s run and checks that they hand
out the same reward at every sample.

Run::

    python examples/generated_module.py                     # module written to a temporary folder
    python examples/generated_module.py -o driving_ra.py    # keep the module
"""

from __future__ import annotations

import argparse
import ast
import importlib.util
import subprocess
import sys
import tempfile
from pathlib import Path

import rac
from rac.lang.resources import stdlib_file


def scripted_run(steps: int) -> list[dict[str, bool | float]]:
    """Inputs for one run: cruise, a close call at 5 s, a stop, a hard start, then on to the goal."""
    run = []
    for k in range(1, steps + 1):
        t = k / 10
        run.append({
            "isClose": 5.0 <= t < 6.0,
            "prog": not 6.0 <= t < 8.0,
            "comf": not 8.0 <= t < 9.0,
            "collide": False,
            "dgoal": max(0.0, 100.0 - 4.0 * t),
        })
    return run


def load_module(path: Path):
    spec = importlib.util.spec_from_file_location(path.stem, path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def imported_modules(path: Path) -> set[str]:
    tree = ast.parse(path.read_text(encoding="utf-8"))
    names = {alias.name.split(".")[0] for node in ast.walk(tree) if isinstance(node, ast.Import)
             for alias in node.names}
    names |= {node.module.split(".")[0] for node in ast.walk(tree)
              if isinstance(node, ast.ImportFrom) and node.module}
    return names


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("-o", "--output", type=Path, help="where to write the generated module")
    args = parser.parse_args(argv)
    source = stdlib_file("driving.ra")
    with tempfile.TemporaryDirectory() as scratch:
        output = args.output or Path(scratch) / "driving_ra.py"
        subprocess.run([sys.executable, "-m", "rac", "compile", "--target", "python", str(source), "-o", str(output)],
                       check=True)
        print(f"generated {output.name}; it imports {', '.join(sorted(imported_modules(output)))}")
        generated = load_module(output).Driving()  # the class is named after the automaton
        interpreted = rac.load(source)

        inputs = scripted_run(interpreted.steps)
        total, location = 0.0, generated.location
        print(f"t =  0.0 s  {location:<13}  objective {generated.objective:8.1f}")
        for k, values in enumerate(inputs, start=1):
            reward = generated.step(values)
            assert reward == interpreted.step(values), f"the targets disagree at sample {k}"
            total += reward
            if generated.location != location:
                location = generated.location
                print(f"t = {k / 10:4.1f} s  {location:<13}  objective {generated.objective:8.1f}  "
                      f"(this sample's reward {reward:+.1f})")
        reward = generated.end(inputs[-1])  # `at end` sees the last sample's inputs
        assert reward == interpreted.end(inputs[-1])
        total += reward
        print(f"end        {generated.location:<13}  objective {generated.objective:8.1f}  "
              f"(goal bonus {reward:+.1f})")
        values = ", ".join(f"{name} = {value:.1f}" for name, value in generated.rewards.items())
        print(f"rewards {values}; the rewards handed out sum to {total:.1f}, "
              f"the final objective is {generated.objective:.1f}")
        print("the generated class and rac.load agree on all", len(inputs), "samples")
    return 0


if __name__ == "__main__":
    sys.exit(main())
