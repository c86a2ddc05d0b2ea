"""`rac verify`'s verdicts on path queries over the automaton's names, against the whole product.

Random small automata (tests/check/test_check_brute_force.py's generator: bool, real and int inputs,
`assume`, one to four locations, `*` edges, rates and updates that read inputs, `at end`, `episode ends
when`) are put in a tiny scene (tests/support/tiny_scenarios.py) with their inputs bound to the model
(a bool to `mindist()` or the speed, a number to `dist_goal()` clamped into its range), and asked random
`A[]`, `E<>`, `E[]` and `A<>` queries over their locations, rewards and inputs. Whatever method
`rac verify` decides a query by (the automaton alone, carried over; a search of the product guided by
the automaton's counterexample; on the fly; exhaustive), its verdict must be the one the complete
product (rac.engine.product.decide_in_model, decided by Storm) gives.
"""

from __future__ import annotations

import os
import random
from fractions import Fraction
from pathlib import Path

from hypothesis import HealthCheck, assume, event, given, settings
from hypothesis import strategies as st
from test_check_brute_force import num, program
from tiny_scenarios import TINY_SCENARIOS

from rac.compiler import compile_file
from rac.engine.product import decide_in_model
from rac.verify.context import VerifyOptions
from rac.verify.runner import run_queries

SETTINGS = settings(max_examples=int(os.environ.get("RAC_EXAMPLES", "15")), deadline=None,
                    derandomize=not os.environ.get("RAC_EXAMPLES"),
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


def bindings(text: str, rng: random.Random) -> list[str]:
    """A binding for every input the program declares."""
    lines = []
    for line in text.splitlines():
        words = line.split()
        if words[:1] != ["input"]:
            continue
        name = words[1]
        if words[3] == "bool":
            lines.append(f"{name} = " + rng.choice(["mindist() < 3 * collision_distance", "v > 8", "v < 8",
                                                    "dist_goal() < 40", "goal()"]))
        else:  # `in [low, high]`: dist_goal() moved and clamped into the range (whole values for an int)
            low, high = (Fraction(w.strip("[],")) for w in words[5:7])
            scaled = rng.choice(["dist_goal() / 10 - 3", "v - 7", "(dist_goal() - 30) / 4"])
            if words[3] == "int":
                scaled = f"round({scaled})"
            lines.append(f"{name} = fmax({num(low)}, fmin({num(high)}, {scaled}))")
    return lines


def queries(text: str, rng: random.Random) -> list[str]:
    # `[initial] location NAME { ... }`
    locations = [line.split("{")[0].split()[-1] for line in text.splitlines() if "location " in line]
    rewards = next(line.split(None, 1)[1] for line in text.splitlines() if line.strip().startswith("reward"))
    rewards = [r.strip() for r in rewards.split(",")]
    inputs = [line.split()[1] for line in text.splitlines() if line.strip().startswith("input")]

    def atom() -> str:
        kind = rng.choice(["location", "reward", "reward", "input"] if inputs else ["location", "reward"])
        if kind == "location":
            return rng.choice(locations)
        if kind == "reward":
            r = rng.choice(rewards)
            return f"{rng.choice(['', '2 * ', '-1 * '])}{r} {rng.choice(['<', '<=', '>', '>='])} " \
                   f"{num(Fraction(rng.randint(-6, 6), rng.choice([1, 2])))}"
        name = rng.choice(inputs)
        if name in ("a", "b"):  # the generator's bool inputs
            return name
        return f"{name} {rng.choice(['<', '>='])} {num(Fraction(rng.randint(-2, 2), 2))}"

    def formula(depth: int = 0) -> str:
        if depth > 1 or rng.random() < 0.5:
            return rng.choice(["", "!"]) + atom() if rng.random() < 0.3 else atom()
        return f"({formula(depth + 1)} {rng.choice(['&&', '||', 'imply'])} {formula(depth + 1)})"

    return [f"    query Q{k}: {rng.choice(['A[]', 'E<>', 'E[]', 'A<>'])} {formula()}" for k in range(4)]


def case(rng: random.Random, folder: Path) -> Path:
    text = program(rng)
    text = "\n".join(line for line in text.splitlines() if not line.strip().startswith("priority"))
    samples = rng.randint(1, 4)
    text = text.replace(next(w for w in text.splitlines() if "sample every" in w), "    sample every 1/2")
    text = text.replace(next(w for w in text.splitlines() if w.strip().startswith("horizon")),
                        f"    horizon {num(Fraction(samples, 2))}")
    scene = rng.choice(["avoidable_obstacle", "goal_ahead"])
    tiny = TINY_SCENARIOS[scene]()
    tiny.write(folder / f"{scene}.xml")
    block = tiny.settings.model_block(f"{scene}.xml", bindings(text, rng))
    body = text.rstrip().removesuffix("}")
    full = body + "".join(f"    {line}\n" for line in block.splitlines()) + "\n".join(queries(text, rng)) + "\n}\n"
    path = folder / "random.ra"
    path.write_text(full, encoding="utf-8")
    return path


def check_case(path: Path) -> None:
    result = compile_file(path)
    assume(result.ok)
    _, answers = run_queries(result, VerifyOptions(seed=1, out_dir=path.parent / "out"))
    text = path.read_text(encoding="utf-8")
    for answer in answers:
        assert answer.status in ("satisfied", "not satisfied", "unsupported"), (answer.status, answer.name, text)
        event(f"{answer.status} ({answer.method})")
        if answer.status == "unsupported":
            continue
        expected = "satisfied" if decide_in_model(result, None, answer.name).holds else "not satisfied"
        assert answer.status == expected, (answer.name, answer.status, answer.method, text)


@SETTINGS
@given(rng=st.randoms(use_true_random=False))
def test_verify_verdicts_over_the_automaton_agree_with_the_whole_product(rng: random.Random,
                                                                         tmp_path: Path) -> None:
    check_case(case(rng, tmp_path))
