"""Fuzzing rac: ``python tests/support/fuzz.py --minutes N [--seed S] [--source both|mutate|generate] [--no-utap]``.

Two sources of inputs (``--source``; the default, ``both``, takes them in turn):

- **mutants** of the shipped `.ra` files (stdlib, examples, the diagnostic examples), each changed
  by a few random mutations: bytes deleted or duplicated, lines swapped, a token replaced by one
  from a pool of troublemakers (huge and tiny numbers, long names, keywords, operators, comment
  openers, CR line endings, a huge action grid, Python builtins and keywords);
- **generated programs** (tests/support/fuzzgen.py): random automata written from the shape of a `.ra`
  file (inputs, constants, rewards, priority, locations, edges, ``at end``, queries, a ``model``
  block), most of them built to pass ``rac check`` (deterministic guards, penalties sized for P2),
  some with extreme values where they still check (1e308, -0.0, 40-digit integers, names UPPAAL
  reserves), some near misses with one or two defects (among them a ``model`` block with a huge
  action grid, ``action jerk in [-20000000, 20000000] step 0.01``: E0901 at once, never a hang).
  Any kind now and then names its automaton, locations, rewards, inputs or constants after
  Python builtins and keywords (``float``, ``len``, ``ValueError``, ``math``, ``class``, ``None``).
  The same generator is a hypothesis strategy in the suite, where a failing program shrinks.

Each input goes through ``rac check``; when it checks, through ``rac fmt`` (idempotent, the
formatted text parses to the same tree and keeps every comment) and ``rac compile`` to both
targets; a model compiled for UPPAAL goes with its queries through UPPAAL's own parser
(``utap_validate``, found as tests/support/utap.py finds it; ``--no-utap`` leaves it out), and the Python
module compiled is imported from the temporary folder and stepped once (every bool False, every
number at its lower bound), giving the reward ``rac.load``'s runtime gives. rac must never fail
internally (exit 3) nor hang (each command has a time limit), UPPAAL's parser must accept every
model rac writes, the Python target must import and step like the runtime, and fmt must behave;
every other outcome is fine. The scenario files the examples and the generated ``model`` blocks
name are copied next to the inputs, so they load.

Two phases for the conditions of the operating system, on some checked inputs:

- **stdout full or closed** (every 20th checked input): ``rac check``, ``rac fmt --stdout`` and
  ``rac compile --target python`` as subprocesses with stdout on ``/dev/full`` and with stdout
  closed must exit 2 with E0009 on stderr, never 3 nor a traceback;
- **concurrent writers** (every 50th): ``rac fmt FILE`` and ``rac tune FILE`` (a file with
  ``param``; otherwise a second ``rac fmt``) started together on a copy must each exit 0 or 2
  (tune refuses when the file changed under it), and the file must then be formatted (``rac fmt
  --check`` exit 0).

Killed sweep tasks (rerun on resume) are too slow for this loop: tests/sweep/test_sweep_task.py keeps them.

The test suite runs bounded numbers of both, and a handful of seeded inputs of each class above
(tests/cli/test_fuzz.py). A long run prints, at its end, the count of each outcome (check ok,
diagnostics, compiled, Python modules stepped and problems, accepted by UPPAAL's parser, UTAP
rejections, fmt problems, stdout full/closed runs and those not E0009 exit 2, concurrent writer
pairs and their problems, internal errors, hangs) and the share of generated programs that passed
``rac check``, by kind. Exit status 1 when something was found; each finding is written to
``--keep DIR`` (default: ``fuzz-failures/``) as ``NNN-KIND.ra``, the input, and ``NNN-KIND.txt``,
what went wrong (for a UTAP rejection, UPPAAL's message with the line it points at).
"""

from __future__ import annotations

import argparse
import contextlib
import importlib.util
import io
import json
import math
import os
import random
import re
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

ROOT = Path(__file__).resolve().parents[2]
if str(ROOT / "src") not in sys.path:  # run as a script from a checkout
    sys.path.insert(0, str(ROOT / "src"))

import fuzzgen  # noqa: E402 - tests/ is the script's folder
import utap  # noqa: E402

import rac  # noqa: E402
from rac.cli.main import main  # noqa: E402
from rac.lang.format import format_module  # noqa: E402
from rac.lang.parser import ParseFailure, parse_text  # noqa: E402

#: Tokens that have broken rac before, or that sit at the edges of what it accepts.
TOKENS = ("1e5000", "1e-5000", "1e308", "1e-307", "0e10000000", "9" * 120, "1e400", "0.0000001", "2147483648",
          "-1", "/*", "*/", "//", "\r", "\r\n", "\t", '"', "{", "}", "(", ")", ";", ",", "&&", "||", "!", "imply",
          "==", "<=", "'", "*", "except", "->", "when", "do", "edge", "location", "initial", "input", "reward", "const",
          "assume", "priority", "objective", "horizon", "sample every", "model", "query", "A[]", "E<>", "Pr[<=1]",
          "under", "strategy", "bind", "allow when", "action", "a" * 5000, "é", "\x00", "🚗", "true", "false",
          "prev(", "mindist()", "collision sticky", "dynamics increments", "offroad_from 1",
          "action jerk in [-20000000, 20000000] step 0.01", "step 1e-9", "float", "ValueError", "class", "None")
#: Seconds a command may take before it counts as a hang.
TIME_LIMIT = 20
SCENARIOS = (ROOT / "examples" / "left_turn" / "left_turn.xml", ROOT / "examples" / "paper" / "left_turn_15s.xml",
             ROOT / "examples" / "stdlib" / "highway.xml", ROOT / "examples" / "stdlib" / "overtaking.xml")
#: Where the inputs come from (``--source``): mutants, generated programs, or the two in turn.
SOURCES = ("both", "mutate", "generate")
#: The OS-conditions phase runs on every this many checked inputs, concurrent writers on every
#: this many (each costs a few subprocesses).
OS_EVERY, WRITERS_EVERY = 20, 50
#: Every this many inputs, ``rac check --format json`` too (:func:`json_problem`).
JSON_EVERY = 3
#: The commands that write to stdout, run with stdout full and closed.
STDOUT_COMMANDS = (["check"], ["fmt", "--stdout"], ["compile", "--target", "python"])


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
    status, out, err = run_apart(argv)
    return status, out + err


def run_apart(argv: list[str]) -> tuple[int, str, str]:
    """``rac ARGV`` in process: its exit status, its stdout and its stderr."""
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err), time_limit(TIME_LIMIT):
        status = main(argv)
    return status, out.getvalue(), err.getvalue()


#: A diagnostic's code: E (error) or W (warning) and four digits.
CODE = re.compile(r"[EW]\d{4}")


def json_problem(source: Path, text: str, status: int) -> str | None:
    """What is wrong with ``rac check --format json``'s document for ``source`` (whose text is ``text``
    and whose text-format check exited with ``status``), or None: it must be one JSON document whose
    diagnostics each have a code, a severity that agrees with the code's letter, a message and a span
    inside the file, and the same exit status, with an error among them exactly when the status is 1."""
    code, out, _ = run_apart(["check", "--format", "json", str(source)])
    if code != status:
        return f"rac check exits {status}, with --format json {code}"
    try:
        document = json.loads(out)
    except ValueError as exc:
        return f"--format json is not JSON ({exc}): {out[:300]!r}"
    lines = text.splitlines() or [""]
    errors = 0
    for entry in document:
        for diagnostic in entry.get("diagnostics", ()):
            label = f"{diagnostic.get('code')}: {str(diagnostic.get('message'))[:120]}"
            if not isinstance(diagnostic.get("code"), str) or not CODE.fullmatch(diagnostic["code"]):
                return f"a diagnostic without a code: {label}"
            severity = {"E": "error", "W": "warning"}[diagnostic["code"][0]]
            if diagnostic.get("severity") != severity:
                return f"{label} has severity {diagnostic.get('severity')!r}"
            if not isinstance(diagnostic.get("message"), str) or not diagnostic["message"].strip():
                return f"{label} has no message"
            errors += severity == "error"
            span = diagnostic.get("span")
            if span is None or Path(span["file"]).name != source.name:
                continue  # a diagnostic of the file as a whole, or of another file (a scenario)
            start, end = (span["line"], span["column"]), (span["end_line"], span["end_column"])
            if not 1 <= span["line"] <= len(lines) + 1 or start > end or span["column"] < 1:
                return f"{label} has span {span} in a file of {len(lines)} lines"
    if (errors > 0) != (status == 1):
        return f"rac check exits {status} with {errors} error(s) in its JSON document"
    return None


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


def python_problem(module_path: Path, source: Path) -> str | None:
    """The Python target's module imported from ``module_path``: it must import, and one
    ``reset``/``step`` (every bool False, every number at its lower bound) must give the reward
    ``rac.load``'s runtime gives (or both refuse the inputs with ValueError, an ``assume``)."""
    spec = importlib.util.spec_from_file_location(f"rac_fuzz_{time.monotonic_ns()}", module_path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    try:
        spec.loader.exec_module(module)
    except Exception as exc:  # noqa: BLE001 - any failure to import is the finding
        return f"the generated module does not import: {type(exc).__name__}: {exc}"
    classes = [value for value in vars(module).values()
               if isinstance(value, type) and value.__module__ == module.__name__ and hasattr(value, "step")]
    if len(classes) != 1:
        return f"the generated module has {len(classes)} automaton classes"
    runtime = rac.load(source)
    inputs: dict[str, object] = {}
    for spec_ in runtime._specs:  # noqa: SLF001 - the declared inputs, as the runtime validates them
        if spec_.is_bool:
            inputs[spec_.name] = False
        else:
            value = spec_.low if math.isfinite(spec_.low) else 0.0 if math.isinf(spec_.high) else spec_.high
            inputs[spec_.name] = int(value) if spec_.kind == "int" else value
    outcomes = []
    for automaton in (classes[0](), runtime):
        automaton.reset()
        try:
            outcomes.append(automaton.step(inputs))
        except ValueError:
            outcomes.append("ValueError")
    compiled, interpreted = outcomes
    if compiled == interpreted or (isinstance(compiled, float) and isinstance(interpreted, float) and (
            math.isclose(compiled, interpreted, rel_tol=1e-9, abs_tol=1e-9)
            or (math.isnan(compiled) and math.isnan(interpreted)))):
        return None
    return f"step({inputs}): the Python target gives {compiled!r}, rac.load's runtime {interpreted!r}"


def rac_process(args: list[str], **options) -> subprocess.CompletedProcess:
    """``python -m rac ARGS`` as a subprocess (this checkout's rac), its stderr captured."""
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    return subprocess.run([sys.executable, "-m", "rac", *args], env=env, stderr=subprocess.PIPE, text=True,
                          timeout=TIME_LIMIT, check=False, **options)


def stdout_problems(source: Path) -> list[str]:
    """Each command of :data:`STDOUT_COMMANDS` with stdout full (``/dev/full``) and closed: what went
    wrong where it did not exit 2 with E0009 (never 3, never a traceback)."""
    problems = []
    for command in STDOUT_COMMANDS:
        for condition in ("full", "closed"):
            if condition == "full":
                with open("/dev/full", "w") as full:  # noqa: PTH123 - Linux's always-full device
                    result = rac_process([*command, str(source)], stdout=full)
            else:
                result = rac_process([*command, str(source)], stdout=subprocess.DEVNULL,
                                     preexec_fn=lambda: os.close(1))  # noqa: PLW1509 - single-threaded
            if result.returncode != 2 or "E0009" not in result.stderr or "Traceback" in result.stderr:
                problems.append(f"rac {' '.join(command)} with stdout {condition}: exit {result.returncode}\n"
                                f"{result.stderr[-400:]}")
    return problems


def writers_problem(text: str, folder: Path) -> str | None:
    """``rac fmt FILE`` and ``rac tune FILE`` (a second ``rac fmt`` without ``param``) started together
    on a copy of ``text``: both exit 0 or 2 (tune refuses when the file changed under it), and the
    file is formatted afterwards."""
    target = folder / "writers.ra"
    target.write_bytes(text.encode("utf-8", "surrogatepass"))
    second = "tune" if re.search(r"^\s*param\b", text, re.MULTILINE) else "fmt"
    env = {**os.environ, "PYTHONPATH": str(ROOT / "src") + os.pathsep + os.environ.get("PYTHONPATH", "")}
    processes = [subprocess.Popen([sys.executable, "-m", "rac", command, str(target)], env=env,
                                  stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
                 for command in ("fmt", second)]
    try:
        errors = [process.communicate(timeout=TIME_LIMIT)[1] for process in processes]
    except subprocess.TimeoutExpired:
        for process in processes:
            process.kill()
            process.wait()
        raise Hang from None
    codes = [process.returncode for process in processes]
    if any(code not in (0, 2) for code in codes):
        return f"rac fmt and rac {second} together: exit {codes[0]} and {codes[1]}\n" + "\n".join(
            e[-400:] for e in errors)
    status, output = run(["fmt", "--check", str(target)])
    if status != 0:
        return f"after rac fmt and rac {second} together, rac fmt --check exits {status}:\n{output[-400:]}"
    return None


def fuzz_one(text: str, folder: Path, report: Report, utap_binary: Path | None = None, *,
             os_every: int = OS_EVERY, writers_every: int = WRITERS_EVERY) -> int | None:
    """Every command on one input; records internal errors, hangs, fmt problems, a Python target
    that does not import or step like the runtime, and (with ``utap_binary``) UPPAAL's parser
    rejecting a compiled model. On every ``os_every``-th checked input, the stdout commands with
    stdout full and closed; on every ``writers_every``-th, concurrent writers (0: never). Returns
    the exit status of ``rac check`` (None when it failed internally or hung)."""
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
        if status in (0, 1) and report.counts["inputs"] % JSON_EVERY == 0:
            problem = json_problem(source, text, status)
            report.counts["json checked"] += 1
            if problem is not None:
                report.fail("json", text, problem)
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
            if target == "python" and status == 0:
                problem = python_problem(folder / out, source)
                if problem is None:
                    report.counts["python stepped"] += 1
                else:
                    report.fail("python target", text, problem)
        if status == 0 and utap_binary is not None:
            complaint = utap_problem(utap_binary, folder)
            if complaint is None:
                report.counts["utap accepted"] += 1
            else:
                report.fail("utap rejection", text, complaint)
        checked_inputs = report.counts["check exit 0"]
        if os_every and checked_inputs % os_every == 0:
            problems = stdout_problems(source)
            report.counts["stdout conditions"] += 2 * len(STDOUT_COMMANDS)
            for problem in problems:
                report.fail("stdout", text, problem)
        if writers_every and checked_inputs % writers_every == 0:
            problem = writers_problem(text, folder)
            report.counts["concurrent writers"] += 1
            if problem is not None:
                report.fail("writers", text, problem)
        return checked
    except (Hang, subprocess.TimeoutExpired):
        report.fail("hang", text, f"a command ran past {TIME_LIMIT} s")
        return None


def scenario_folder(folder: Path) -> Path:
    """``folder`` with the scenario files the shipped examples and generated programs name."""
    for scenario in SCENARIOS:
        shutil.copy(scenario, folder / scenario.name)
    return folder


def fuzz(seed: int, *, inputs: int | None = None, seconds: float | None = None, source: str = "mutate",
         utap_binary: Path | None = None, os_every: int = OS_EVERY, writers_every: int = WRITERS_EVERY) -> Report:
    """Fuzz with ``seed`` for ``inputs`` inputs or ``seconds`` seconds, whichever ends first: mutants
    of the shipped files, generated programs (:mod:`fuzzgen`) or both in turn (``source``, one of
    :data:`SOURCES`). With ``utap_binary``, UPPAAL's parser reads every model compiled for UPPAAL;
    ``os_every`` and ``writers_every`` as in :func:`fuzz_one`."""
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
                fuzz_one(mutate(text, rng), folder, report, utap_binary, os_every=os_every,
                         writers_every=writers_every)
                continue
            program = fuzzgen.generate(choices)
            report.counts[f"generated {program.kind}"] += 1
            if fuzz_one(program.text, folder, report, utap_binary, os_every=os_every,
                        writers_every=writers_every) == 0:
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
    rows += [("python module stepped", c["python stepped"]), ("python target problems", c["python target"]),
             ("UTAP accepted", c["utap accepted"]), ("UTAP rejections", c["utap rejection"]),
             ("fmt problems", c["fmt"]),
             ("stdout full/closed runs", c["stdout conditions"]), ("  not E0009 exit 2", c["stdout"]),
             ("concurrent writer pairs", c["concurrent writers"]), ("  writer problems", c["writers"]),
             ("internal errors", c["internal error"]), ("hangs", c["hang"])]
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
        located = utap.locate()  # RAC_UTAP_VALIDATE, else ../shared/tools/uppaal-parser (tests/support/utap.py)
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
