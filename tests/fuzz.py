"""Fuzzing rac: ``python tests/fuzz.py --minutes N [--seed S] [--source both|mutate|generate] [--no-utap]``.

Two sources of inputs (``--source``; the default, ``both``, takes them in turn):

- **mutants** of the shipped `.ra` files (stdlib, examples, the diagnostic examples), each changed
  by a few random mutations: bytes deleted or duplicated, lines swapped, a token replaced by one
  from a pool of troublemakers (huge and tiny numbers, long names, keywords, operators, comment
  openers, CR line endings);
- **generated programs** (tests/fuzzgen.py): random automata written from the shape of a `.ra`
  file (inputs, constants, rewards, priority, locations, edges, ``at end``, queries, a ``model``
  block), most of them built to pass ``rac check`` (deterministic guards, penalties sized for P2),
  some with extreme values where they still check (1e308, -0.0, 40-digit integers, names UPPAAL
  reserves), some near misses with one or two defects. The same generator is a hypothesis
  strategy in the suite, where a failing program shrinks.

Each input goes through ``rac check``; when it checks, through ``rac fmt`` (idempotent, the
formatted text parses to the same tree and keeps every comment) and ``rac compile`` to both
targets; a model compiled for UPPAAL goes with its queries through UPPAAL's own parser
(``utap_validate``, found as tests/utap.py finds it; ``--no-utap`` leaves it out). rac must never
fail internally (exit 3) nor hang (each command has a time limit), UPPAAL's parser must accept
every model rac writes, and fmt must behave; every other outcome is fine. The scenario files the
examples and the generated ``model`` blocks name are copied next to the inputs, so they load.

The test suite runs bounded numbers of both (tests/test_fuzz.py). A long run prints, at its end,
the count of each outcome (check ok, diagnostics, compiled, accepted by UPPAAL's parser, internal
errors, hangs, UTAP rejections, fmt problems) and the share of generated programs that passed
``rac check``, by kind. Exit status 1 when something was found; each finding is written to
``--keep DIR`` (default: ``fuzz-failures/``) as ``NNN-KIND.ra``, the input, and ``NNN-KIND.txt``,
what went wrong (for a UTAP rejection, UPPAAL's message with the line it points at).
"""

from __future__ import annotations

import argparse
import contextlib
import io
import random
import shutil
import signal
import subprocess
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

import fuzzgen  # noqa: E402 - tests/ is the script's folder
import utap  # noqa: E402

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
#: Where the inputs come from (``--source``): mutants, generated programs, or the two in turn.
SOURCES = ("both", "mutate", "generate")


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
    """Why ``rac fmt`` misbehaves on ``text`` (not idempotent, the meaning changed, a comment lost),
    or None."""
    try:
        tree = parse_text(text, "fuzz.ra")
    except ParseFailure:
        return None
    first = format_module(tree)
    try:
        formatted = parse_text(first, "fuzz.ra")
    except ParseFailure as failure:
        return f"the formatted text does not parse: {failure.diagnostic.message}"
    if format_module(formatted) != first:
        return "not idempotent"
    if formatted != tree:  # the trees compare without spans and comments
        return "the formatted text parses to a different tree"
    if len(formatted.comments) != len(tree.comments):
        return f"{len(tree.comments)} comments before formatting, {len(formatted.comments)} after"
    return None


def utap_problem(binary: Path, folder: Path) -> str | None:
    """UPPAAL's parser (``utap_validate``) on the model and queries just compiled into ``folder``
    (``out.xml``, ``out.q``): its complaint, or None when it accepts both."""
    command = [str(binary), "-q", "out.q", "out.xml"]
    try:
        result = subprocess.run(command, cwd=folder, capture_output=True, text=True, timeout=TIME_LIMIT,
                                check=False)
    except subprocess.TimeoutExpired:
        raise Hang from None
    if result.returncode == 0:
        return None
    xml, queries = (folder / "out.xml").read_text(encoding="utf-8"), (folder / "out.q").read_text(encoding="utf-8")
    return f"utap_validate exit {result.returncode}:\n" + utap.explain(result.stdout + result.stderr, xml, queries)


def fuzz_one(text: str, folder: Path, report: Report, utap_binary: Path | None = None) -> int | None:
    """Every command on one input; records internal errors, hangs, fmt problems and (with
    ``utap_binary``) UPPAAL's parser rejecting a compiled model. Returns the exit status of
    ``rac check`` (None when it failed internally or hung)."""
    source = folder / "fuzz.ra"
    source.write_bytes(text.encode("utf-8", "surrogatepass"))
    report.counts["inputs"] += 1
    try:
        status, output = run(["check", str(source)])
        if status == 3 or "internal error" in output:
            report.fail("internal error", text, f"rac check: {output[-400:]}")
            return None
        checked = status
        report.counts[f"check exit {status}"] += 1
        if status != 0:
            return checked
        problem = fmt_problem(text)
        if problem is not None:
            report.fail("fmt", text, problem)
        for target, out in (("python", "out.py"), ("uppaal", "out.xml")):
            for stale in (folder / out, folder / "out.q"):
                stale.unlink(missing_ok=True)
            status, output = run(["compile", "--target", target, str(source), "-o", str(folder / out)])
            if status == 3 or "internal error" in output:
                report.fail("internal error", text, f"rac compile --target {target}: {output[-400:]}")
                return checked
            report.counts[f"compile {target} exit {status}"] += 1
        if status == 0 and utap_binary is not None:
            complaint = utap_problem(utap_binary, folder)
            if complaint is None:
                report.counts["utap accepted"] += 1
            else:
                report.fail("utap rejection", text, complaint)
        return checked
    except Hang:
        report.fail("hang", text, f"a command ran past {TIME_LIMIT} s")
        return None


def scenario_folder(folder: Path) -> Path:
    """``folder`` with the scenario files the shipped examples and generated programs name."""
    for scenario in SCENARIOS:
        shutil.copy(scenario, folder / scenario.name)
    return folder


def fuzz(seed: int, *, inputs: int | None = None, seconds: float | None = None, source: str = "mutate",
         utap_binary: Path | None = None) -> Report:
    """Fuzz with ``seed`` for ``inputs`` inputs or ``seconds`` seconds, whichever ends first: mutants
    of the shipped files, generated programs (:mod:`fuzzgen`) or both in turn (``source``, one of
    :data:`SOURCES`). With ``utap_binary``, UPPAAL's parser reads every model compiled for UPPAAL."""
    if source not in SOURCES:
        raise ValueError(f"source {source!r}: one of {', '.join(SOURCES)}")
    rng = random.Random(seed)
    choices = fuzzgen.RandomChoices(rng)
    files = corpus()
    report = Report()
    start = time.monotonic()
    with tempfile.TemporaryDirectory(prefix="rac-fuzz-") as name:
        folder = scenario_folder(Path(name))
        while (inputs is None or report.counts["inputs"] < inputs) and (
                seconds is None or time.monotonic() - start < seconds):
            if source == "mutate" or (source == "both" and report.counts["inputs"] % 2 == 0):
                _, text = rng.choice(files)
                report.counts["mutants"] += 1
                fuzz_one(mutate(text, rng), folder, report, utap_binary)
                continue
            program = fuzzgen.generate(choices)
            report.counts[f"generated {program.kind}"] += 1
            if fuzz_one(program.text, folder, report, utap_binary) == 0:
                report.counts[f"generated {program.kind} check ok"] += 1
    return report


def generated_share(report: Report) -> tuple[int, int]:
    """How many generated programs passed ``rac check``, of how many."""
    return (sum(report.counts[f"generated {kind} check ok"] for kind in fuzzgen.KINDS),
            sum(report.counts[f"generated {kind}"] for kind in fuzzgen.KINDS))


def summary(report: Report) -> list[str]:
    """The counts a run prints at its end, one outcome a line."""
    c = report.counts
    rows = [("inputs", c["inputs"]), ("  mutants", c["mutants"]), ("  generated", generated_share(report)[1]),
            ("check ok (exit 0)", c["check exit 0"]), ("check diagnostics (exit 1)", c["check exit 1"]),
            ("check unreadable (exit 2)", c["check exit 2"])]
    for target in ("python", "uppaal"):
        rows += [(f"compile {target} ok", c[f"compile {target} exit 0"]),
                 (f"compile {target} diagnostics", c[f"compile {target} exit 1"] + c[f"compile {target} exit 2"])]
    rows += [("UTAP accepted", c["utap accepted"]), ("UTAP rejections", c["utap rejection"]),
             ("fmt problems", c["fmt"]), ("internal errors", c["internal error"]), ("hangs", c["hang"])]
    lines = [f"{what:30} {count:>8,}" for what, count in rows]
    passed, generated = generated_share(report)
    if generated:
        kinds = ", ".join(f"{kind} {c[f'generated {kind} check ok']:,}/{c[f'generated {kind}']:,}"
                          for kind in fuzzgen.KINDS)
        lines.append(f"{'generated passing check':30} {passed / generated:>8.1%}  ({kinds})")
    return lines


def main_fuzz(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--minutes", type=float, default=1.0, help="how long to fuzz (default 1)")
    parser.add_argument("--seed", type=int, default=1, help="seed of the mutations (default 1)")
    parser.add_argument("--keep", type=Path, default=Path("fuzz-failures"), help="where failing inputs go")
    parser.add_argument("--source", choices=SOURCES, default="both",
                        help="mutants of the shipped files, generated programs, or both in turn (default both)")
    parser.add_argument("--no-utap", action="store_true",
                        help="do not pass the compiled UPPAAL models to UPPAAL's parser (utap_validate)")
    args = parser.parse_args(argv)
    binary = None
    if not args.no_utap:
        located = utap.locate()  # RAC_UTAP_VALIDATE, else ../shared/tools/uppaal-parser (tests/utap.py)
        binary = located.path
        print(f"UPPAAL's parser: {binary}" if binary else located.reason.splitlines()[0], file=sys.stderr)
    start = time.monotonic()
    report = fuzz(args.seed, seconds=args.minutes * 60, source=args.source, utap_binary=binary)
    elapsed = time.monotonic() - start
    print(f"source {args.source}, seed {args.seed}")
    for line in summary(report):
        print(line)
    print(f"{'seconds':30} {elapsed:>8.0f}")
    if report.failures:
        args.keep.mkdir(parents=True, exist_ok=True)
        for i, (what, text, detail) in enumerate(report.failures):
            stem = args.keep / f"{i:03d}-{what.replace(' ', '_')}"
            stem.with_suffix(".ra").write_text(text, encoding="utf-8", errors="replace")
            stem.with_suffix(".txt").write_text(detail + "\n", encoding="utf-8", errors="replace")
            print(f"{what}: {detail.splitlines()[-1] if detail else ''} ({stem}.ra)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main_fuzz())
