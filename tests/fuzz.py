"""Fuzzing rac with mutants of the shipped `.ra` files: ``python tests/fuzz.py --minutes N [--seed S]``.

Each input is a shipped `.ra` file (stdlib, examples, the diagnostic examples) changed by a few
random mutations — bytes deleted or duplicated, lines swapped, a token replaced by one from a pool
of troublemakers (huge and tiny numbers, long names, keywords, operators, comment openers, CR
line endings). Each goes through ``rac check``; when it checks, through ``rac fmt`` (which must be
idempotent and keep every comment) and ``rac compile`` to both targets. rac must never fail
internally (exit 3) nor hang (each command has a time limit); every other outcome is fine. The
scenario files the examples name are copied next to the inputs, so model blocks load.

The test suite runs a bounded number of inputs (tests/test_fuzz.py); long runs print the counts
that docs/benchmarks.md quotes. Exit status 1 when an internal error or a hang was found; the
inputs that caused them are written to ``--keep DIR`` (default: ``fuzz-failures/``).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import random
import shutil
import signal
import sys
import tempfile
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
if str(ROOT / "src") not in sys.path:  # run as a script from a checkout
    sys.path.insert(0, str(ROOT / "src"))

from rac.cli.main import main  # noqa: E402
from rac.lang.format import format_module  # noqa: E402
from rac.lang.parser import ParseFailure, parse_text  # noqa: E402

#: Tokens that have broken rac before, or that sit at the edges of what it accepts.
TOKENS = ("1e5000", "1e-5000", "1e308", "1e-307", "0e10000000", "9" * 120, "1e400", "0.0000001", "2147483648",
          "-1", "/*", "*/", "//", "\r", "\r\n", "\t", '"', "{", "}", "(", ")", ";", ",", "&&", "||", "!", "imply",
          "==", "<=", "'", "*", "except", "->", "when", "do", "edge", "location", "initial", "input", "reward", "const",
          "assume", "priority", "objective", "horizon", "sample every", "model", "query", "A[]", "E<>", "Pr[<=1]",
          "under", "strategy", "bind", "allow when", "action", "a" * 5000, "é", "\x00", "🚗", "true", "false",
          "prev(", "mindist()", "collision sticky", "dynamics increments", "offroad_from 1")
#: Seconds a command may take before it counts as a hang.
TIME_LIMIT = 20
SCENARIOS = (ROOT / "examples" / "left_turn" / "left_turn.xml", ROOT / "examples" / "paper" / "left_turn_15s.xml")


def corpus() -> list[tuple[str, str]]:
    """The shipped `.ra` files (name, text)."""
    files = sorted([*ROOT.glob("stdlib/*.ra"), *ROOT.glob("examples/**/*.ra"), *ROOT.glob("tests/diagnostics/*.ra")])
    return [(path.name, path.read_text(encoding="utf-8")) for path in files]


def mutate(text: str, rng: random.Random) -> str:
    """``text`` with 1 to 4 random mutations (a third of the time only a number replaced, so that
    many mutants still check and go on through fmt and both targets)."""
    gentle = rng.random() < 0.35
    for _ in range(1 if gentle else rng.randint(1, 4)):
        kind = 4 if gentle else rng.randrange(5)
        if not text:
            return rng.choice(TOKENS)
        at = rng.randrange(len(text))
        if kind == 0:  # delete a range
            text = text[:at] + text[at + rng.randint(1, 40):]
        elif kind == 1:  # duplicate a range
            text = text[:at] + text[at:at + rng.randint(1, 80)] + text[at:]
        elif kind == 2:  # insert a troublemaker
            text = text[:at] + " " + rng.choice(TOKENS) + " " + text[at:]
        elif kind == 3:  # swap two lines
            lines = text.split("\n")
            i, j = rng.randrange(len(lines)), rng.randrange(len(lines))
            lines[i], lines[j] = lines[j], lines[i]
            text = "\n".join(lines)
        else:  # replace a number
            digits = [i for i, ch in enumerate(text) if ch.isdigit()]
            if digits:
                i = rng.choice(digits)
                text = text[:i] + rng.choice(TOKENS[:10]) + text[i + 1:]
    return text


class Hang(BaseException):
    """A command ran past :data:`TIME_LIMIT` (a BaseException: rac's own handler of unexpected
    exceptions must not take it for an internal error)."""


@contextlib.contextmanager
def time_limit(seconds: int) -> Iterator[None]:
    def expire(signum, frame):  # noqa: ARG001 - signal handler signature
        raise Hang

    previous = signal.signal(signal.SIGALRM, expire)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def run(argv: list[str]) -> tuple[int, str]:
    """``rac ARGV`` in process: its exit status and its output (stdout and stderr)."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), time_limit(TIME_LIMIT):
        status = main(argv)
    return status, out.getvalue() + err.getvalue()


@dataclass
class Report:
    """What a fuzzing run found: outcomes by kind, and the inputs behind the failures."""

    counts: Counter = field(default_factory=Counter)
    failures: list[tuple[str, str, str]] = field(default_factory=list)  # (what, input text, detail)

    def fail(self, what: str, text: str, detail: str) -> None:
        self.counts[what] += 1
        self.failures.append((what, text, detail))


def fmt_problem(text: str) -> str | None:
    """Why ``rac fmt`` misbehaves on ``text`` (not idempotent, a comment lost), or None."""
    try:
        first = format_module(parse_text(text, "fuzz.ra"))
    except ParseFailure:
        return None
    try:
        second = format_module(parse_text(first, "fuzz.ra"))
    except ParseFailure as failure:
        return f"the formatted text does not parse: {failure.diagnostic.message}"
    if second != first:
        return "not idempotent"
    return None


def fuzz_one(text: str, folder: Path, report: Report) -> None:
    """Every command on one input; records internal errors and hangs."""
    source = folder / "fuzz.ra"
    source.write_bytes(text.encode("utf-8", "surrogatepass"))
    report.counts["inputs"] += 1
    commands = [["check", str(source)]]
    try:
        status, output = run(commands[0])
        if status == 3 or "internal error" in output:
            report.fail("internal error", text, f"rac check: {output[-400:]}")
            return
        report.counts[f"check exit {status}"] += 1
        if status != 0:
            return
        problem = fmt_problem(text)
        if problem is not None:
            report.fail("fmt", text, problem)
        for target, out in (("python", "out.py"), ("uppaal", "out.xml")):
            status, output = run(["compile", "--target", target, str(source), "-o", str(folder / out)])
            if status == 3 or "internal error" in output:
                report.fail("internal error", text, f"rac compile --target {target}: {output[-400:]}")
                return
            report.counts[f"compile {target} exit {status}"] += 1
    except Hang:
        report.fail("hang", text, f"a command ran past {TIME_LIMIT} s")


def fuzz(seed: int, *, inputs: int | None = None, seconds: float | None = None) -> Report:
    """Fuzz with ``seed`` for ``inputs`` inputs or ``seconds`` seconds, whichever ends first."""
    rng = random.Random(seed)
    files = corpus()
    report = Report()
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="rac-fuzz-") as name:
        folder = Path(name)
        for scenario in SCENARIOS:
            shutil.copy(scenario, folder / scenario.name)
        while (inputs is None or report.counts["inputs"] < inputs) and (
                seconds is None or time.monotonic() - start < seconds):
            _, text = rng.choice(files)
            fuzz_one(mutate(text, rng), folder, report)
    return report


def main_fuzz(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=1.0, help="how long to fuzz (default 1)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the mutations (default 1)")
    parser.add_argument("--keep", type=Path, default=Path("fuzz-failures"), help="where failing inputs go")
    args = parser.parse_args(argv)
    start = time.monotonic()
    report = fuzz(args.seed, seconds=args.minutes * 60)
    elapsed = time.monotonic() - start
    for what, count in sorted(report.counts.items()):
        print(f"{what:28} {count:>8,}")
    print(f"{'seconds':28} {elapsed:>8.0f}")
    if report.failures:
        args.keep.mkdir(parents=True, exist_ok=True)
        for i, (what, text, detail) in enumerate(report.failures):
            (args.keep / f"{i:03d}-{what.replace(' ', '_')}.ra").write_text(text, encoding="utf-8", errors="replace")
            print(f"{what}: {detail.splitlines()[-1] if detail else ''}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main_fuzz())
