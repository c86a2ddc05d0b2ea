"""``rac check``, ``rac compile`` and ``rac fmt``: the commands on `.ra` files themselves, and
:func:`read_and_check`, which every command that reads a `.ra` file uses."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Iterable
from pathlib import Path
from typing import TYPE_CHECKING

from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_OK,
    EXIT_UNDECIDED,
    EXIT_USAGE,
    FileWriteError,
    as_json,
    check_writable,
    interrupts_as_such,
    load_budget,
    locked,
    not_generated,
    overwrites_source,
    print_diagnostics,
    same_file,
    unreadable,
    unusable_file,
    unwritable,
    usage_error,
    write_all_atomically,
    write_atomically,
)
from rac.compiler import CompileResult, compile_file
from rac.core.diagnostics import (
    UNFINISHED,
    Diagnostic,
    display_text,
    error,
    json_text,
    leaves_undecided,
    render_text,
    sort_key,
)
from rac.core.source import MAX_SOURCE_BYTES
from rac.lang.format import format_module
from rac.lang.parser import ParseFailure, parse_source, read_source
from rac.model.commonroad import ScenarioError
from rac.model.data import ModelRangeError
from rac.output.progress import Heartbeat, notice

if TYPE_CHECKING:
    from rac.check.analysis.discount import Discount

__all__ = ["check_command", "compile_command", "fmt_command", "read_and_check"]


def read_and_check(path: Path, max_bytes: int | None = None, discount: Discount | None = None
                   ) -> tuple[CompileResult | None, Diagnostic | None]:
    """``rac check`` of one file, or the E0008 diagnostic when it cannot be read at all. ``max_bytes``:
    the memory budget of the scenario's load (``--max-memory``; None: no limit); a scenario estimated
    to need more raises :class:`rac.core.resources.ScenarioTooLarge` before it loads. ``discount``: P2
    of the discounted return checked too (``--discount``)."""
    try:
        return compile_file(path, progress=notice(), max_bytes=max_bytes, discount=discount), None
    except OSError as exc:
        return None, unreadable(path, exc)
    finally:  # the load's phases are over: the command names its next
        if Heartbeat.active is not None:
            Heartbeat.active.phase("")



def _discount_of(args: argparse.Namespace) -> Discount | None:
    """``--discount`` and ``--samples-per-step`` as one :class:`~rac.check.analysis.discount.Discount`, or None."""
    if args.discount is None:
        return None
    from rac.check.analysis.discount import Discount  # numpy and the analyses: only when asked

    return Discount(args.discount, args.samples_per_step or 1)


def check_command(args: argparse.Namespace) -> int:
    # off a terminal (CI logs, pipes) a long check (a large scenario's load) says what it does
    with Heartbeat("rac check"):
        return _check_files(args)


def _check_entry(path: Path, *, ok: bool, diagnostics: Iterable[Diagnostic] = (), proved: Iterable[str] = (),
                 facts: Iterable[object] = (), undecided: bool = False, **extra: object) -> dict[str, object]:
    """One file's entry in ``rac check --format json``'s array: every outcome (checked, unreadable, stopped by
    Ctrl-C) has the same fields, ``{"file", "ok", "diagnostics", "proved", "facts", "undecided"}``, and ``extra``:
    a script reads them all without a case for each."""
    return {"file": str(path), "ok": ok, "diagnostics": [d.to_json() for d in sorted(diagnostics, key=sort_key)],
            "proved": list(proved), "facts": list(facts), "undecided": undecided, **extra}


def _check_files(args: argparse.Namespace) -> int:
    status = EXIT_OK
    undecided = False  # a check stopped at its limit: exit 4 unless something worse happened
    report: list[dict[str, object]] = []
    max_bytes = load_budget(args)
    if args.samples_per_step is not None and args.discount is None:
        print_diagnostics([usage_error("--samples-per-step says how many samples a discounted step spans; it "
                                       "needs --discount", hints=["add --discount GAMMA (0.99: stable-baselines3's "
                                                                  "default gamma)"])],
                          structured=args.format == "json")
        return EXIT_USAGE
    discount = _discount_of(args)
    for path in args.files:
        try:
            with interrupts_as_such():  # Ctrl-C in an extension's import (numpy's) is one too
                result, failure = read_and_check(path, max_bytes, discount)
        except KeyboardInterrupt:  # Ctrl-C, SIGTERM: the files checked before stay in the one document
            if args.format == "json":
                report.append(_check_entry(path, ok=False, undecided=True, interrupted=True))
                print(json_text(report, indent=2))
            raise  # rac.cli.main says how it stopped and exits 130 or 143
        if result is None:
            assert failure is not None
            status = max(status, EXIT_USAGE)
            report.append(_check_entry(path, ok=False, diagnostics=[failure]))
            if args.format == "text":
                print(render_text([failure], {}), file=sys.stderr)
            continue
        errors = sum(d.is_error for d in result.diagnostics)
        warnings = len(result.diagnostics) - errors
        if errors:
            status = max(status, EXIT_ERRORS)
        undecided = undecided or result.undecided
        if args.format == "json":
            report.append(_check_entry(path, ok=errors == 0, diagnostics=result.diagnostics, proved=result.proved,
                                       facts=[fact.to_json() for fact in result.facts], undecided=result.undecided))
            continue
        if result.diagnostics:
            print(render_text(result.diagnostics, result.sources))
            print()
        left_open = [] if errors else [d for d in result.diagnostics if leaves_undecided(d)]
        unfinished = sum(d.code == UNFINISHED for d in left_open)
        undone = len(left_open) - unfinished  # required checks that could not be made (W1008)
        # no error but a check that stopped at its limit: not every verdict either
        summary = f"{errors} error{'s' * (errors != 1)}" if errors else "undecided" if left_open else "ok"
        if warnings:
            summary += f", {warnings} warning{'s' * (warnings != 1)}"
        if unfinished:
            summary += (f" ({unfinished} of them: a check stopped at its limit or outside what it covers, "
                        "neither proved nor refuted)")
        if undone:
            summary += f" ({undone} of them: a required check not made, neither proved nor refuted)"
        print(f"{path}: {summary}")
        if not args.quiet:
            for fact in result.proved:
                print(f"  proved: {fact}")
    if args.format == "json":
        print(json_text(report, indent=2))
    return EXIT_UNDECIDED if status == EXIT_OK and undecided else status


def compile_command(args: argparse.Namespace) -> int:
    """``rac compile``: the target's code to ``-o FILE`` (or standard output). With ``--format json``
    standard output is one JSON document: the diagnostics when it fails (:func:`print_diagnostics`),
    else :func:`_compiled_json`'s summary of what was written."""
    # off a terminal the checks before the code (a long horizon's worst-run search, a large scenario's load)
    # say what they do, as under rac check: a compile of a 300,000-sample horizon was silent for 27 s
    with Heartbeat("rac compile"):
        return _compile(args)


def _compile(args: argparse.Namespace) -> int:
    result, failure = read_and_check(args.file, load_budget(args))
    diagnostics = [failure] if failure else list(result.diagnostics if result else [])
    failed = result is None or not result.ok
    if diagnostics and (failed or args.format == "text"):
        print_diagnostics(diagnostics, result.sources if result else {}, as_json(args))
    if result is None:
        return EXIT_USAGE
    if not result.ok or result.automaton is None:
        return EXIT_ERRORS
    status = _generate(args, result)
    if status == EXIT_OK and result.undecided:
        # a check stopped at its limit (W0405) or a required one not made (W1008): the code is written, but
        # the file is undecided, and exits as `rac check` does on it (4), never as a file that passed (0)
        if not as_json(args):
            print(f"note: `{display_text(str(args.file))}` is undecided: a check was not made (the warnings above "
                  "say which), so the code is written but the exit status is 4, as `rac check` gives",
                  file=sys.stderr)
        return EXIT_UNDECIDED
    return status


def _generate(args: argparse.Namespace, result: CompileResult) -> int:
    """The target's code of the checked ``result`` written (or printed); the exit status."""
    assert result.automaton is not None, "only a file without errors is compiled"
    outputs = [args.output] if args.output is not None else []
    if args.output is not None:
        try:  # a folder (`-o ./`, `-o /`: no name to derive the .q file from), a FIFO, a device
            check_writable(args.output)
        except OSError as exc:
            print_diagnostics([unwritable(args.output, exc)], {}, as_json(args))
            return EXIT_USAGE
    if args.output is not None and args.target == "uppaal":
        # jinja2, numpy (via rac.targets.uppaal.automaton): rac --help, fmt and a syntax error never load it
        from rac.targets.uppaal.automaton import queries_path

        outputs.append(Path(queries_path(str(args.output))))
    for output in outputs:
        if same_file(output, args.file):
            print_diagnostics([overwrites_source(output, args.file)], {}, as_json(args))
            return EXIT_USAGE
        foreign = not_generated(output)
        if foreign is not None:  # a hand-written module or model of the same name
            print_diagnostics([foreign], {}, as_json(args))
            return EXIT_USAGE
    if args.target == "uppaal":
        return _compile_uppaal(args, result)
    # jinja2, numpy (via rac.targets.python): rac --help, fmt and a syntax error never load it
    from rac.targets.python import generate_python, module_name_note, python_class_name

    text = generate_python(result.automaton, source_name=display_text(args.file.name))
    name = result.automaton.name
    if python_class_name(name) != name:  # whoever imports the class must know what it is called
        print(f"note: the class is `{python_class_name(name)}`: `{name}` is a Python keyword or a name the "
              "module itself uses", file=sys.stderr)
    if args.output is None:
        _emit(args, result, text)
        return EXIT_OK
    note = module_name_note(args.output)  # whoever imports the module must be able to name it
    if note is not None:
        print(f"note: {display_text(note)}", file=sys.stderr)
    try:
        write_atomically(args.output, text)
    except OSError as exc:
        print_diagnostics([unwritable(args.output, exc)], {}, as_json(args))
        return EXIT_USAGE
    _wrote(args, result, [args.output])
    return EXIT_OK


def _compiled_json(args: argparse.Namespace, result: CompileResult, written: list[Path], text: str | None) -> str:
    """``rac compile --format json`` after it succeeded: the file, the target, the files written (``-o``),
    the generated text when it went nowhere else (no ``-o``: it is in the document, not beside it), whether
    a check was left undecided and the file's diagnostics (its warnings), as ``rac check --format json`` has them."""
    return json_text({"file": str(args.file), "target": args.target, "ok": True, "undecided": result.undecided,
                      "written": [str(path) for path in written], "output": text,
                      "diagnostics": [d.to_json() for d in sorted(result.diagnostics, key=sort_key)]}, indent=2)


def _emit(args: argparse.Namespace, result: CompileResult, text: str) -> None:
    """The generated ``text`` without ``-o``: on standard output, or in the JSON summary with ``--format json``."""
    if as_json(args):
        print(_compiled_json(args, result, [], text))
    else:
        sys.stdout.write(text)


def _wrote(args: argparse.Namespace, result: CompileResult, written: list[Path]) -> None:
    """Say what ``rac compile -o`` wrote: a line on standard error, or the JSON summary on standard output."""
    if as_json(args):
        print(_compiled_json(args, result, written, None))
    else:
        print(f"wrote {' and '.join(str(path) for path in written)}", file=sys.stderr)


def _compile_uppaal(args: argparse.Namespace, result: CompileResult) -> int:
    """``--target uppaal``: the model to ``-o FILE.xml`` and its queries to ``FILE.q`` beside it."""
    # jinja2, numpy (via rac.targets.uppaal.automaton): rac --help, fmt and a syntax error never load it
    from rac.targets.uppaal.automaton import UppaalError, generate_uppaal, queries_path

    output: Path | None = args.output
    queries = Path(queries_path(str(output))) if output is not None else None
    if output is not None and queries == output:
        print_diagnostics([error("E0009", f"cannot write `{output}`: the model's queries go to a file of that name",
                                 None, hints=["name the model FILE.xml; nothing was written"])], {}, as_json(args))
        return EXIT_USAGE
    assert result.automaton is not None
    try:
        if result.automaton.model is not None:
            # jinja2, numpy (via rac.targets.uppaal.model): rac --help, fmt and a syntax error never load it
            from rac.targets.uppaal.model import generate_uppaal_model

            # With a `model` block: the whole model in its scenario (docs/uppaal.md).
            model = generate_uppaal_model(result.checked(), source_name=display_text(args.file.name),
                                          model_name=display_text(output.name) if output is not None else "")
        else:
            model = generate_uppaal(result.automaton, source_name=display_text(args.file.name),
                                    model_name=display_text(output.name) if output is not None else "")
    except (ScenarioError, ModelRangeError) as failure:  # the checks load the scenario first; a safety net
        print_diagnostics([unusable_file(f"`{args.file}`: cannot build the scenario model: {failure}")], {},
                          as_json(args))
        return EXIT_ERRORS
    except UppaalError as failure:  # JSON: with the file's warnings, as a failed check has them
        shown = [*result.diagnostics, *failure.diagnostics] if as_json(args) else failure.diagnostics
        print_diagnostics(shown, result.sources, as_json(args))
        return EXIT_ERRORS
    if output is None or queries is None:
        _emit(args, result, model.xml)
        return EXIT_OK
    try:
        write_all_atomically([(output, model.xml), (queries, model.queries)])
    except FileWriteError as exc:
        print_diagnostics([unwritable(exc.path, exc.cause)], {}, as_json(args))
        return EXIT_USAGE
    _wrote(args, result, [output, queries])
    if output.suffix != ".xml":  # UPPAAL's tools (verifyta, the GUI, UTAP) read any other name as XTA text
        print(f"note: `{output}` holds an XML model, but UPPAAL reads a file as XML only when its name ends in "
              f"`.xml` (any other as the textual XTA format, which this is not): name it `{output.name}.xml`",
              file=sys.stderr)
    return EXIT_OK


def fmt_command(args: argparse.Namespace) -> int:
    status = EXIT_OK
    for path in args.files:
        with locked(path):  # read, format and write while no other rac rewrites the file
            status = max(status, _fmt_one(args, path))
    return status


def _fmt_one(args: argparse.Namespace, path: Path) -> int:
    """``rac fmt`` of one file; its exit status."""

    source = None
    try:
        source = read_source(path)
        formatted = format_module(parse_source(source))
        # the bytes, not the decoded text: a BOM or CR line ends differ from the output too
        unchanged = formatted.encode("utf-8") == path.read_bytes()
    except OSError as exc:
        print(render_text([unreadable(path, exc)], {}), file=sys.stderr)
        return EXIT_USAGE
    except ParseFailure as failure:
        shown = source or failure.source
        print(render_text([failure.diagnostic], {shown.name: shown} if shown else {}), file=sys.stderr)
        return EXIT_ERRORS
    size = len(formatted.encode("utf-8"))
    if size > MAX_SOURCE_BYTES:  # the aligned columns' padding grew it past what rac reads back (E0005)
        print(render_text([error(
            "E0005", f"`{path}` formatted is too large ({size:,} bytes; at most {MAX_SOURCE_BYTES:,}): rac could "
                     "not read it back, so it is left as it is", None,
            hints=["the layout pads runs of declarations to their longest line: shorter names in long runs keep "
                   "the file within the limit"])], {}), file=sys.stderr)
        return EXIT_ERRORS
    if args.stdout:
        sys.stdout.write(formatted)
        if args.check and not unchanged:  # both: the result printed, and the check's verdict kept
            print(f"{path}: would be reformatted", file=sys.stderr)
            return EXIT_ERRORS
    elif unchanged:
        pass
    elif args.check:
        print(f"{path}: would be reformatted", file=sys.stderr)
        return EXIT_ERRORS
    else:
        try:
            write_atomically(path, formatted)
        except OSError as exc:
            print(render_text([unwritable(path, exc)], {}), file=sys.stderr)
            return EXIT_USAGE
        print(f"{path}: reformatted", file=sys.stderr)
    return EXIT_OK


