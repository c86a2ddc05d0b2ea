"""How ``rac check`` scales with generated inputs: ``python benchmarks/check.py [--quick] [--timeout S]``.

Three families of generated ``.ra`` files, each at several sizes; every size is checked by
``python -m rac check -q`` in a child process of its own (the time includes starting Python,
about 0.3 s), killed after ``--timeout`` seconds (default 120). The table gives per size the
file's size, the wall time and what the check said (error and warning codes).

  unreachable  n locations, each entered only from the initial location by an edge whose guard
               is contradictory (``d < 10 && d > 20 + i``), each with its own outgoing edges
               (thresholds of their own on a second input ``e``) and reward flows.
  reachable    the same automaton with satisfiable, adjacent intervals instead
               (``d > a_i && d <= a_i+1 && e > a_i``): every location is reachable and every
               guard adds thresholds, so the input classes grow as n^2.
  samples      stdlib/driving.ra sampled every 0.001 s, at horizons of 30 s to 359 s
               (30,000 to 359,000 samples; P2 fails and a reward overflows int32 there).
  discounted   stdlib/driving.ra (every 0.1 s) at horizons of 300 to 20,000 samples, with PENALTY raised
               to 2 * horizon + 100, `Unsafe` absorbing and no collision loop (so P2 and the int32 range
               hold), checked with
               ``--discount 0.99``: P2 of the discounted return, E0410 at every size.
  updates      five inputs (three numeric, read by the flows and updates), updates that scale and
               copy rewards (not translations, so the int32 range check takes the exact generic
               search), at horizons of 10 to 60 samples: hundreds of input classes per location.

The results are written to ``benchmarks/results/check.md`` as well (``--output``).
"""

from __future__ import annotations

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time
from collections.abc import Callable, Sequence
from pathlib import Path

HERE = Path(__file__).resolve().parent
REPOSITORY = HERE.parent
DEFAULT_OUTPUT = HERE / "results" / "check.md"

try:  # benchmark the installed rac; in a checkout without it, the checkout's src/
    import rac
except ImportError:
    sys.path.insert(0, str(REPOSITORY / "src"))
    import rac

SIZES = {"unreachable": (25, 50, 100, 200), "reachable": (25, 50, 100, 200), "samples": (30, 90, 180, 359),
         "discounted": (300, 3000, 10000, 20000), "updates": (10, 30, 60)}
QUICK_SIZES = {"unreachable": (25, 50), "reachable": (25, 50), "samples": (30,), "discounted": (300,),
               "updates": (10,)}
#: The options of ``rac check`` per family (none: the plain check).
OPTIONS = {"discounted": ("--discount", "0.99")}


def locations_text(n: int, *, reachable: bool) -> str:
    """An automaton with ``n`` locations besides ``Start``, entered by contradictory or by satisfiable guards."""
    lines = ["automaton Slow {",
             "    input d : real in [0, 100]",
             "    input e : real in [0, 100]",
             "    input b : bool",
             "    reward sa, pr, co",
             "    priority sa > pr > co",
             "    objective 100*sa + 10*pr + co",
             "    sample every 0.1",
             "    horizon 30",
             "    initial location Start { sa' == 1; pr' == 1; co' == 0 }"]
    lines += [f"    location L{i} {{ sa' == -1; pr' == 0; co' == 0 }}" for i in range(n)]
    for i in range(n):
        low, high = f"{100 * (i + 1) / (n + 1):.3f}", f"{100 * (i + 2) / (n + 1):.3f}"
        guard = f"d > {low} && d <= {high} && e > {low}" if reachable else f"d < 10 && d > {20 + i}"
        lines.append(f"    edge Start -> L{i} when {guard} && b do sa = sa - 100")
        lines.append(f"    edge L{i} -> Start when e > {low} && !b")
        lines.append(f"    edge L{i} -> L{(i + 1) % n} when e <= {low} && !b do co = co + 1")
    lines.append("}")
    return "\n".join(lines) + "\n"


def samples_text(horizon: int) -> str:
    """stdlib/driving.ra sampled every millisecond over ``horizon`` seconds."""
    from rac.lang.resources import stdlib_file

    text = stdlib_file("driving.ra").read_text(encoding="utf-8")
    text, one = re.subn(r"(?m)^(\s*sample every\s+)0\.1\b", r"\g<1>0.001", text)
    text, two = re.subn(r"(?m)^(\s*horizon\s+)30\b", rf"\g<1>{horizon}", text)
    if one != 1 or two != 1:
        raise SystemExit("benchmarks/check.py: cannot find `sample every 0.1` and `horizon 30` in stdlib/driving.ra")
    return text


def discounted_text(samples: int) -> str:
    """stdlib/driving.ra over ``samples`` samples of 0.1 s, its penalty raised so that P2 holds, `Unsafe`
    absorbing and without the collision loop (so that the rewards stay within int32)."""
    from rac.lang.resources import stdlib_file

    seconds = samples // 10
    text = stdlib_file("driving.ra").read_text(encoding="utf-8")
    text, one = re.subn(r"(?m)^(\s*horizon\s+)30\b", rf"\g<1>{seconds}", text)
    text, two = re.subn(r"(?m)^(\s*const PENALTY = )100\b", rf"\g<1>{2 * seconds + 100}", text)
    text, three = re.subn(r"(?m)^\s*edge Unsafe -> Unsafe .*\n", "", text)
    # Unsafe absorbing: a penalty every other sample would leave int32 at 3,000 samples (E0501)
    text, four = re.subn(r"(?m)^(\s*edge \*) (-> (?:Stalled|Uncomfortable|Normal)\b)", r"\g<1> except Unsafe \g<2>",
                         text)
    if (one, two, three, four) != (1, 1, 1, 3):
        raise SystemExit("benchmarks/check.py: cannot find `horizon 30`, `const PENALTY = 100`, the collision "
                         "loop and the three `*` edges out of Unsafe in stdlib/driving.ra")
    return text


def updates_text(samples: int) -> str:
    """Rewards scaled and copied by updates that read numeric inputs, over ``samples`` samples of 0.1 s."""
    return f"""automaton Scaled {{
    input p, q : bool
    input d    : real in [-1, 1]
    input e    : real in [0, 0.3]
    input n    : int in [-3, 3]
    assume p imply n != 0
    assume q imply d < 1/3
    reward s, m, c
    objective 1000 * s + 3 * m + c / 7
    sample every 0.1
    horizon {samples / 10:g}
    initial location A {{ s' == 0.1; m' == d / 3 + e * 7 + 0.2; c' == n - d }}
    location B {{ s' == -1; m' == 0; c' == e }}
    location C {{ s' == 0.3; m' == -0.5 }}
    edge A -> B when p || d > 1/3 do s -= 10, m = m / 3 + d, c = m
    edge B -> C when !p && n >= 1 && e <= 0.1 do c = c + 2 * d - n
    edge C -> A when !p && q
    edge C -> B when p do s = s - 10 - e
    edge B -> A when !p && n < 1 && d <= 1/3 && !q
    at end when d > 0.5 do m += 0.7
    at end when n == -3 do c = c * 3 + 1, m = m + c
    episode ends when q && n == 3 && e > 0.25
}}
"""


FAMILIES: dict[str, Callable[[int], str]] = {
    "unreachable": lambda n: locations_text(n, reachable=False),
    "reachable": lambda n: locations_text(n, reachable=True),
    "samples": samples_text,
    "discounted": discounted_text,
    "updates": updates_text,
}


def run_check(path: Path, timeout: float, options: Sequence[str] = ()) -> tuple[float | None, str]:
    """Wall time of ``python -m rac check -q [options] path`` (None past ``timeout``) and the codes it reported."""
    env = dict(os.environ, PYTHONPATH=os.pathsep.join(
        [str(Path(rac.__file__).resolve().parent.parent), *filter(None, [os.environ.get("PYTHONPATH")])]))
    command = [sys.executable, "-m", "rac", "check", "--format", "json", *options, str(path)]
    start = time.perf_counter()
    try:
        done = subprocess.run(command, env=env, capture_output=True, text=True, timeout=timeout)
    except subprocess.TimeoutExpired:
        return None, "-"
    elapsed = time.perf_counter() - start
    if done.returncode not in (0, 1, 4):  # 4: a check stopped at its limit (W0405), reported below
        return elapsed, f"exit {done.returncode}"
    codes: dict[str, int] = {}
    for code in re.findall(r'"code": "([EW]\d{4})"', done.stdout):
        codes[code] = codes.get(code, 0) + 1
    return elapsed, ", ".join(f"{c} x{k}" if k > 1 else c for c, k in sorted(codes.items())) or "ok"


def main(argv: Sequence[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--quick", action="store_true", help="the smallest sizes only (a smoke run)")
    parser.add_argument("--timeout", type=float, default=120.0, help="seconds before a check is killed")
    parser.add_argument("--only", choices=sorted(FAMILIES), help="one family")
    parser.add_argument("--output", type=Path, default=DEFAULT_OUTPUT)
    args = parser.parse_args(argv)
    sizes = QUICK_SIZES if args.quick else SIZES
    rows = ["| family | size | file | time | diagnostics |", "|---|---:|---:|---:|---|"]
    print(f"rac from {Path(rac.__file__).resolve().parent}")
    with tempfile.TemporaryDirectory() as folder:
        for family, make in FAMILIES.items():
            if args.only and family != args.only:
                continue
            for size in sizes[family]:
                path = Path(folder) / f"{family}_{size}.ra"
                path.write_text(make(size), encoding="utf-8")
                elapsed, codes = run_check(path, args.timeout, OPTIONS.get(family, ()))
                shown = f"> {args.timeout:g} s" if elapsed is None else f"{elapsed:.2f} s"
                what = (f"{size * 1000:,} samples" if family == "samples"
                        else f"{size:,} samples" if family in ("updates", "discounted") else f"{size} locations")
                row = f"| {family} | {what} | {path.stat().st_size / 1000:.1f} kB | {shown} | {codes} |"
                rows.append(row)
                print(row, flush=True)
    args.output.parent.mkdir(parents=True, exist_ok=True)
    args.output.write_text("\n".join(rows) + "\n", encoding="utf-8")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
