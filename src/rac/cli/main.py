"""The ``rac`` command: check, compile and format `.ra` files, tune their parameters
(:mod:`rac.cli.tune`), start one from the standard library (:mod:`rac.cli.new`); verify, simulate, render and
pre-analyse them with the native engine (:mod:`rac.cli.engine`).

Exit codes: 0 clean (warnings allowed), 1 errors in the input, 2 bad usage, a file that cannot be
read or written (standard output too), or memory that ran out (a resource, not the input), 3 an
internal error (a bug in rac; set RAC_DEBUG=1 for the traceback).
"""

from __future__ import annotations

import argparse
import errno
import json
import os
import sys
from collections.abc import Sequence
from pathlib import Path
from typing import TextIO

from rac import __version__
from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_INTERNAL,
    EXIT_OK,
    EXIT_USAGE,
    OUTPUT_CONVENTION,
    FileWriteError,
    StdoutError,
    load_budget,
    locked,
    overwrites_source,
    read_and_check,
    same_file,
    size_argument,
    stdout_unwritable,
    unreadable,
    unwritable,
    write_all_atomically,
    write_atomically,
)
from rac.compiler import CompileResult
from rac.core.diagnostics import render_json, render_text, sort_key
from rac.model.checks import ScenarioTooLarge

TARGETS = ("python", "uppaal")


def _parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="rac", description="The reward-automata compiler: check, compile and format .ra files; verify "
                    "their queries, simulate and pre-analyse them on a CommonRoad scenario.",
        epilog=f"{OUTPUT_CONVENTION} Exit codes: 0 ok, 1 errors in the input or a query not satisfied, 2 bad "
               "usage or a file that cannot be read or written (standard output too), 3 an internal error (a "
               "bug in rac), 4 a query not decided.")
    parser.add_argument("--version", action="version", version=f"rac {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    check = commands.add_parser("check", help="type-check files and prove or refute their priority order")
    check.add_argument("files", nargs="+", type=Path, metavar="FILE")
    check.add_argument("--format", choices=("text", "json"), default="text", help="output format")
    check.add_argument("-q", "--quiet", action="store_true", help="print diagnostics only, not what was proved")
    check.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                       help="refuse, before loading it, a scenario whose load would need more memory than this, "
                            "e.g. 4G (default: half the machine's memory)")

    compile_ = commands.add_parser("compile", help="generate code for a target")
    compile_.add_argument("file", type=Path, metavar="FILE")
    compile_.add_argument("--target", choices=TARGETS, required=True)
    compile_.add_argument("-o", "--output", type=Path, help="output file (default: standard output)")
    compile_.add_argument("--format", choices=("text", "json"), default="text", help="diagnostics format")
    compile_.add_argument("--max-memory", type=size_argument, default=None, metavar="SIZE",
                          help="as for `rac check` (default: half the machine's memory)")

    fmt = commands.add_parser("fmt", help="rewrite files in canonical layout (comments are kept)")
    fmt.add_argument("files", nargs="+", type=Path, metavar="FILE")
    fmt.add_argument("--check", action="store_true", help="only report files that would change (exit 1)")
    fmt.add_argument("--stdout", action="store_true", help="print the result instead of rewriting")

    from rac.cli.engine import add_parsers
    from rac.cli.new import add_parser as add_new
    from rac.cli.sweep import add_parser as add_sweep
    from rac.cli.tune import add_parser as add_tune

    add_tune(commands)
    add_parsers(commands)
    add_sweep(commands)
    add_new(commands)
    return parser


def _check(args: argparse.Namespace) -> int:
    from rac.output.progress import Heartbeat

    # off a terminal (CI logs, pipes) a long check (a large scenario's load) says what it does
    with Heartbeat("rac check"):
        return _check_files(args)


def _check_files(args: argparse.Namespace) -> int:
    status = EXIT_OK
    report: list[dict[str, object]] = []
    max_bytes = load_budget(args)
    for path in args.files:
        result, failure = read_and_check(path, max_bytes)
        if result is None:
            assert failure is not None
            status = max(status, EXIT_USAGE)
            report.append({"file": str(path), "ok": False, "diagnostics": [failure.to_json()], "proved": []})
            if args.format == "text":
                print(render_text([failure], {}), file=sys.stderr)
            continue
        errors = sum(d.is_error for d in result.diagnostics)
        warnings = len(result.diagnostics) - errors
        if errors:
            status = max(status, EXIT_ERRORS)
        if args.format == "json":
            report.append({"file": str(path), "ok": errors == 0,
                           "diagnostics": [d.to_json() for d in sorted(result.diagnostics, key=sort_key)],
                           "proved": list(result.facts)})
            continue
        if result.diagnostics:
            print(render_text(result.diagnostics, result.sources))
            print()
        summary = "ok" if not errors else f"{errors} error{'s' * (errors != 1)}"
        if warnings:
            summary += f", {warnings} warning{'s' * (warnings != 1)}"
        print(f"{path}: {summary}")
        if not args.quiet:
            for fact in result.facts:
                print(f"  proved: {fact}")
    if args.format == "json":
        print(json.dumps(report, indent=2))
    return status


def _compile_command(args: argparse.Namespace) -> int:
    result, failure = read_and_check(args.file, load_budget(args))
    diagnostics = [failure] if failure else list(result.diagnostics if result else [])
    failed = result is None or not result.ok
    if diagnostics and (failed or args.format == "text"):
        if args.format == "json":
            print(render_json(diagnostics))
        else:
            print(render_text(diagnostics, result.sources if result else {}), file=sys.stderr)
    if result is None:
        return EXIT_USAGE
    if not result.ok or result.automaton is None:
        return EXIT_ERRORS
    outputs = [args.output] if args.output is not None else []
    if args.output is not None and args.target == "uppaal":
        from rac.targets.uppaal.automaton import queries_path

        outputs.append(Path(queries_path(str(args.output))))
    for output in outputs:
        if same_file(output, args.file):
            print(render_text([overwrites_source(output, args.file)], {}), file=sys.stderr)
            return EXIT_USAGE
    if args.target == "uppaal":
        return _compile_uppaal(args, result)
    from rac.targets.python import generate_python, python_class_name

    text = generate_python(result.automaton, source_name=args.file.name)
    name = result.automaton.name
    if python_class_name(name) != name:  # whoever imports the class must know what it is called
        print(f"note: the class is `{python_class_name(name)}`: `{name}` is a Python keyword or a name the "
              "module itself uses", file=sys.stderr)
    if args.output is None:
        sys.stdout.write(text)
    else:
        try:
            write_atomically(args.output, text)
        except OSError as exc:
            print(render_text([unwritable(args.output, exc)], {}), file=sys.stderr)
            return EXIT_USAGE
        print(f"wrote {args.output}", file=sys.stderr)
    return EXIT_OK


def _compile_uppaal(args: argparse.Namespace, result: CompileResult) -> int:
    """``--target uppaal``: the model to ``-o FILE.xml`` and its queries to ``FILE.q`` beside it."""
    from rac.model.commonroad import ScenarioError
    from rac.model.data import ModelRangeError
    from rac.targets.uppaal.automaton import UppaalError, generate_uppaal, queries_path

    output: Path | None = args.output
    queries = Path(queries_path(str(output))) if output is not None else None
    if output is not None and queries == output:
        print(f"rac: `{output}` cannot hold the model: its queries go to a file of that name; "
              "name the model FILE.xml", file=sys.stderr)
        return EXIT_USAGE
    assert result.automaton is not None
    try:
        if result.automaton.model is not None:
            from rac.targets.uppaal.model import generate_uppaal_model

            # With a `model` block: the whole model in its scenario (docs/uppaal.md).
            model = generate_uppaal_model(result.checked(), source_name=args.file.name,
                                          model_name=output.name if output is not None else "")
        else:
            model = generate_uppaal(result.automaton, source_name=args.file.name,
                                    model_name=output.name if output is not None else "")
    except (ScenarioError, ModelRangeError) as failure:  # the checks load the scenario first; a safety net
        print(f"rac: {args.file}: cannot build the scenario model: {failure}", file=sys.stderr)
        return EXIT_ERRORS
    except UppaalError as failure:
        if args.format == "json":
            print(render_json([*result.diagnostics, *failure.diagnostics]))
        else:
            print(render_text(failure.diagnostics, result.sources), file=sys.stderr)
        return EXIT_ERRORS
    if output is None or queries is None:
        sys.stdout.write(model.xml)
        return EXIT_OK
    try:
        write_all_atomically([(output, model.xml), (queries, model.queries)])
    except FileWriteError as exc:
        print(render_text([unwritable(exc.path, exc.cause)], {}), file=sys.stderr)
        return EXIT_USAGE
    print(f"wrote {output} and {queries}", file=sys.stderr)
    return EXIT_OK


def _fmt(args: argparse.Namespace) -> int:
    status = EXIT_OK
    for path in args.files:
        with locked(path):  # read, format and write while no other rac rewrites the file
            status = max(status, _fmt_one(args, path))
    return status


def _fmt_one(args: argparse.Namespace, path: Path) -> int:
    """``rac fmt`` of one file; its exit status."""
    from rac.lang.format import format_module
    from rac.lang.parser import ParseFailure, parse_source, read_source

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
    if args.stdout:
        sys.stdout.write(formatted)
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


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``rac`` command; returns the exit code."""
    stderr = sys.stderr
    sys.stderr = StderrSafe(stderr)  # type: ignore[assignment]  # `rac check x.ra 2>&-`: still its own status
    try:
        return _main(argv)
    finally:
        sys.stderr = stderr


def _main(argv: Sequence[str] | None) -> int:
    parser = _parser()
    try:
        args = parser.parse_args(argv)
    except SystemExit as exc:  # argparse exits 2 on bad usage, 0 on --help
        return int(exc.code or 0)
    from rac.cli.engine import HANDLERS
    from rac.cli.new import new_command
    from rac.cli.sweep import sweep_command
    from rac.cli.tune import tune_command

    handlers = {"check": _check, "compile": _compile_command, "fmt": _fmt, "tune": tune_command, **HANDLERS,
                "sweep": sweep_command, "new": new_command}
    stdout = sys.stdout
    sys.stdout = ReaderSafe(stdout)  # `rac check ... | head`: the command still ends with its own status
    try:
        status = handlers[args.command](args)
        sys.stdout.flush()  # here, not at exit: a full disk is reported like any other write
        return status
    except StdoutError as exc:  # the environment's, not a bug: say what failed, exit 2
        print(render_text([stdout_unwritable(exc.cause)], {}), file=sys.stderr)
        return EXIT_USAGE
    except KeyboardInterrupt:
        print("rac: interrupted", file=sys.stderr)
        return 130
    except ScenarioTooLarge as exc:  # refused before loading: the budget, not the file, is at fault
        print(f"rac: resource limit: {exc}", file=sys.stderr)
        return EXIT_USAGE
    except MemoryError as exc:  # the machine or the process limit ran out, not a bug and not a broken input
        if os.environ.get("RAC_DEBUG"):
            raise
        print(f"rac: out of memory{': ' + str(exc) if str(exc) else ''}: rac needed more memory than this process "
              "may use (the machine's memory, or a limit such as `ulimit -v`); the input files are not at fault: "
              "raise the limit, or lower --max-memory (where the command has it) so that rac stops before it",
              file=sys.stderr)
        return EXIT_USAGE
    except Exception as exc:  # a bug in rac: say so plainly instead of a traceback
        if os.environ.get("RAC_DEBUG"):
            raise
        print(f"rac: internal error: {type(exc).__name__}: {exc}\n"
              "This is a bug in rac; rerun with RAC_DEBUG=1 for the traceback and report it.", file=sys.stderr)
        return EXIT_INTERNAL
    finally:
        sys.stdout = stdout


class ReaderSafe:
    """Standard output that outlives its reader. When the reader leaves (``rac check ... | head -1``),
    the rest of the output is dropped and the command goes on to its own exit status: a failed check
    stays failed whoever reads its first line.

    Any other failure to write (a full disk, a closed standard output) raises :class:`StdoutError`,
    once: later output is dropped, so that the report of it and the exit go through.
    """

    def __init__(self, stream: TextIO | None) -> None:
        self._stream = stream
        self.gone = False

    def write(self, text: str) -> int:
        if not self.gone:
            try:
                if self._stream is None:  # started with standard output closed (`rac ... >&-`)
                    raise OSError(errno.EBADF, "standard output is closed")
                return self._stream.write(text)
            except BrokenPipeError:
                self._reader_left()
            except OSError as exc:
                self._reader_left()
                raise StdoutError(exc) from exc
        return len(text)

    def flush(self) -> None:
        if not self.gone and self._stream is not None:
            try:
                self._stream.flush()
            except BrokenPipeError:
                self._reader_left()
            except OSError as exc:
                self._reader_left()
                raise StdoutError(exc) from exc

    def _reader_left(self) -> None:
        self.gone = True
        if self._stream is None:
            return
        try:  # later flushes of the real stream (at exit too) go to /dev/null, silently
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


class StderrSafe:
    """Standard error that never fails the command. Closed (``rac check x.ra 2>&-``) or unwritable
    (``2>/dev/full``), its messages are dropped: there is nowhere left to report that failure, and the
    command's exit status (its verdict, or the error it reports) is the one it would have had.
    """

    def __init__(self, stream: TextIO | None) -> None:
        self._stream = stream
        self.gone = stream is None

    def write(self, text: str) -> int:
        if not self.gone and self._stream is not None:
            try:
                return self._stream.write(text)
            except (OSError, ValueError):  # ValueError: the stream itself was closed
                self._drop()
        return len(text)

    def flush(self) -> None:
        if not self.gone and self._stream is not None:
            try:
                self._stream.flush()
            except (OSError, ValueError):
                self._drop()

    def _drop(self) -> None:
        self.gone = True
        try:  # the real stream's buffered text, flushed again at exit, goes to /dev/null, silently
            devnull = os.open(os.devnull, os.O_WRONLY)
            os.dup2(devnull, self._stream.fileno())  # type: ignore[union-attr]
            os.close(devnull)
        except (OSError, ValueError, AttributeError):
            pass

    def isatty(self) -> bool:
        return not self.gone and self._stream is not None and self._stream.isatty()

    def __getattr__(self, name: str):
        return getattr(self._stream, name)


def entry() -> None:
    sys.exit(main())


if __name__ == "__main__":
    entry()
