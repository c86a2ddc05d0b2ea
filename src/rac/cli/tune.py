"""``rac tune FILE.ra``: synthesise a file's ``param`` values (what ``rac check`` does) and write them
back as constants, or show them (``--print``), or tabulate them over horizons (``--horizon``).

The write-back edits only the text of each ``param`` declaration: it becomes one ``const NAME = VALUE``
line per name (VALUE exact: an integer or ``a / b``), under a comment recording the declaration and
the set that was synthesised, so every other character of the file stays. A file that was in
``rac fmt`` layout is formatted again (its comments kept). The result is checked before it is written:
``rac check`` must prove of it what it proved of the parametrised file, or nothing is written.
docs/tune.md has a worked example.
"""

from __future__ import annotations

import argparse
import difflib
import errno
import re
import sys
from dataclasses import dataclass
from fractions import Fraction
from pathlib import Path

from rac.check.analysis.synthesis import Synthesised
from rac.check.horizon import Fit, at_horizon, fit_line, formula_text
from rac.cli.common import (
    EXIT_ERRORS,
    EXIT_INTERRUPTED,
    EXIT_OK,
    EXIT_USAGE,
    how_stopped,
    interrupts_as_such,
    load_budget,
    locked,
    resource_limit,
    unreadable,
    unwritable,
    usage_error,
    write_atomically,
)
from rac.compiler import CompileResult, compile_source
from rac.core.diagnostics import Diagnostic, counted, error, json_text, render_text, short_number, sort_key
from rac.core.numbers import exact_decimal, exact_text
from rac.core.resources import ScenarioTooLarge
from rac.core.source import SourceFile
from rac.lang import ast
from rac.lang.format import format_module
from rac.lang.parser import MAX_DIGITS, ParseFailure, number_problem, parse_source, parse_text, read_source
from rac.output.progress import Heartbeat, notice

__all__ = ["tune_command", "tuned_text"]



@dataclass(frozen=True)
class _Row:
    """One horizon of the table: the synthesised values, or the errors that left none."""

    horizon: Fraction
    synthesis: Synthesised | None
    errors: tuple[Diagnostic, ...]


def tune_command(args: argparse.Namespace) -> int:
    """``rac tune``: see the module docstring. Exit 0, 1 when synthesis fails, 2 on bad usage (or a
    scenario beyond ``--max-memory``: a resource limit, in the command's JSON document too)."""
    try:
        # off a terminal the synthesis (every check, at each --horizon) and a large scenario's load say what
        # they do, as under rac check; rac tune was silent through both
        with Heartbeat("rac tune"):
            return _tune(args)
    except ScenarioTooLarge as exc:
        return _refused(args, args.file, resource_limit(f"resource limit: {exc}"))


def _refused(args: argparse.Namespace, path: Path, diagnostic: Diagnostic, status: int = EXIT_USAGE) -> int:
    """The file cannot be tuned as asked (unreadable, no `param`, a bad ``--horizon``, not written):
    ``diagnostic`` on standard error, or in the command's JSON document (:func:`_failed`); exit ``status``."""
    if args.format == "json":  # a script parses standard output: the usual document, not text
        return _failed(args, path, CompileResult(None, (diagnostic,), {}), status)
    print(render_text([diagnostic], {}), file=sys.stderr)
    return status


def _tune(args: argparse.Namespace) -> int:
    path: Path = args.file
    source: SourceFile | None = None
    try:
        source = read_source(path)
        module = parse_source(source)
    except OSError as exc:
        return _refused(args, path, unreadable(path, exc))
    except ParseFailure as failure:
        shown = source or failure.source
        return _failed(args, path, CompileResult(None, (failure.diagnostic,), {shown.name: shown} if shown else {}))
    if len(module.automata) > 1:  # E0107 (a param of the second one is no reason to say "no param")
        return _failed(args, path, compile_source(source, analyse=False))
    node = module.automata[0] if module.automata else None
    if node is None or not node.of(ast.ParamDecl):
        return _refused(args, path, usage_error(
            f"`{path}` declares no `param`: there is nothing to tune",
            notes=["`param NAME in [lo, hi]` declares a constant whose value rac synthesises: the least value in "
                   "the bounds for which every check holds"],
            hints=["write e.g. `param PENALTY in [0, 1000]` in place of `const PENALTY = 100` and run "
                   f"`rac tune {path}` again (`rac check` shows what it synthesises)"]))
    if args.horizon is not None:
        return _horizons(args, source, node)
    result = _synthesised(source, args)
    if not result.ok or result.synthesis is None:
        return _failed(args, path, result)
    synthesis = result.synthesis
    refused = _unwritable(node, synthesis)
    if refused is not None:  # the tuned file would not parse: refused before anything is written
        return _failed(args, path, CompileResult(None, (*result.diagnostics, refused), result.sources))
    text = tuned_text(source, module, synthesis)
    _confirm(source, text, result)
    written = None
    if not args.show:
        with locked(path):  # rac fmt (or another tune) may have rewritten the file while this one worked
            try:
                changed = read_source(path).text != source.text
                if not changed:
                    write_atomically(path, text)
            except (OSError, ParseFailure) as exc:
                cause = exc if isinstance(exc, OSError) else OSError(errno.EIO, "it can no longer be read")
                return _refused(args, path, unwritable(path, cause))
        if changed:
            return _refused(args, path, error(
                "E0009", f"cannot write `{path}`: it changed since rac tune read it (another program wrote it "
                         "meanwhile); nothing was written, so that its changes are kept", None,
                hints=[f"run `rac tune {path}` again"]))
        written = path
    changes = list(difflib.unified_diff(source.text.splitlines(), text.splitlines(), str(path),
                                        f"{path} (tuned)", n=0, lineterm=""))
    if args.format == "json":
        print(json_text({"file": str(path), "ok": True, **_values_json(synthesis),
                         "sentence": synthesis.sentence, "written": None if written is None else str(written),
                         "diff": changes, "diagnostics": _diagnostics_json(result.diagnostics)}, indent=2))
        return EXIT_OK
    if result.diagnostics:  # warnings: they hold for the tuned file too
        print(render_text(result.diagnostics, result.sources))
        print()
    print(f"{path}: {', '.join(f'{name} = {_value_text(value)}' for name, value in synthesis.values)}")
    print(f"  {synthesis.sentence}")
    print(f"wrote {path}:" if written is not None else f"would write {path} (rac tune without --print):")
    for line in changes:
        print(line)
    return EXIT_OK


def _synthesised(source: SourceFile, args: argparse.Namespace, phase: str = "synthesising") -> CompileResult:
    """``source`` checked, its parameters synthesised: a large scenario's load announced (as ``rac check``
    announces it); off a terminal the heartbeat says ``phase``, or the load's while it lasts."""
    if Heartbeat.active is not None:
        Heartbeat.active.phase(phase)
    try:
        return compile_source(source, max_bytes=load_budget(args), progress=notice())
    finally:  # the load's phases are over: the synthesis goes on under its own
        if Heartbeat.active is not None:
            Heartbeat.active.phase(phase)


def tuned_text(source: SourceFile, module: ast.Module, synthesis: Synthesised) -> str:
    """``source``'s text with every ``param`` declaration of its automaton replaced by ``const`` lines
    at the values of ``synthesis``, each under a ``// rac tune:`` comment recording the declaration
    and the set; formatted again when ``source`` was in ``rac fmt`` layout and that keeps every comment."""
    values = dict(synthesis.values)
    text = source.text
    for decl in reversed(module.automata[0].of(ast.ParamDecl)):
        assert decl.span is not None, "a parsed declaration has its place"
        names = [n.name for n in decl.names]
        held = [i for i in synthesis.inequalities if any(re.search(rf"\b{re.escape(n)}\b", i) for n in names)]
        record = (f"// rac tune: {' '.join(text[decl.span.start:decl.span.end].split())}; every check holds for "
                  + (" and ".join(held) if held else "every value in these bounds"))
        text = _replaced(text, decl.span.start, decl.span.end,
                         [record, *(f"const {n} = {exact_text(values[n])}" for n in names)])
    if format_module(module) == source.text:
        try:
            formatted = format_module(parse_text(text, source.name))
        except ParseFailure:
            return text
        if _comments(formatted) == _comments(text):
            return formatted
    return text


def _unwritable(node: ast.Automaton, synthesis: Synthesised) -> Diagnostic | None:
    """E0015 when a synthesised value cannot be written back as a `.ra` number (:func:`tuned_text` writes
    ``a / b`` exactly, each at most :data:`~rac.lang.parser.MAX_DIGITS` digits): a value below 1e-307 in
    size (``sa -= P * 6e307`` gives ``P = 7.5e-308``), or one whose exact terms are longer. The file checks
    with the parameter; written as a constant it would not parse, so rac tune writes nothing."""
    for name, value in synthesis.values:
        if all(number_problem(str(abs(part))) is None for part in (value.numerator, value.denominator)):
            continue
        size = abs(value)
        small, large = 0 < size < Fraction(1, 10**307), size > 10**308
        why = ("below 1e-307 in size, the smallest number other than 0 that a `.ra` file (and a double) holds"
               if small else "beyond 1e308, the largest number a `.ra` file holds" if large else
               f"a fraction whose exact numerator or denominator needs more than {MAX_DIGITS} digits")
        scaled = ("declare it scaled up (its bounds 1e300 times larger, and `{name} * 1e-300` where it is used)"
                  if small else "declare it scaled down (its bounds 1e300 times smaller, and `{name} * 1e300` "
                  "where it is used)" if large else "narrow its bounds so that the least value is a shorter number")
        decl = next((d for d in node.of(ast.ParamDecl) if name in (n.name for n in d.names)), None)
        return error("E0015", f"cannot write `{name}` back as a constant: its synthesised value, "
                     f"{short_number(value)}, is {why}; nothing was written",
                     None if decl is None else decl.span,
                     notes=[synthesis.sentence],
                     hints=[f"{scaled.format(name=name)} and run rac tune again, or write `const {name} = ...` "
                            "with a value of your own in its place"])
    return None


def _replaced(text: str, start: int, end: int, lines: list[str]) -> str:
    """``text`` with ``[start, end)`` replaced by ``lines`` at its indentation (on a line of their own
    when something precedes the region on its line). Where own-line comments
    continue a trailing comment after the region (in its column), that column is kept, so the
    formatter still reads them as one comment."""
    newline = "\r\n" if "\r\n" in text else "\n"  # the file's own line ends
    line_start = text.rfind("\n", 0, start) + 1
    prefix = text[line_start:start]
    indent = prefix if not prefix.strip() else prefix[:len(prefix) - len(prefix.lstrip())]
    replacement = ("" if not prefix.strip() else newline + indent) + (newline + indent).join(lines)
    line_end = text.find("\n", end)
    line_end = len(text) if line_end < 0 else line_end
    after = text[end:line_end]
    old_column = end - line_start
    column = old_column + len(after) - len(after.lstrip())  # the trailing comment's
    below = text[line_end:].split("\n")
    continued = 0
    while (after.strip() and "\n" not in text[start:end] and continued + 1 < len(below)
           and below[continued + 1].lstrip().startswith("//")
           and len(below[continued + 1]) - len(below[continued + 1].lstrip()) == column):
        continued += 1
    if not continued:
        return text[:start] + replacement + text[end:]
    shift = len(indent) + len(lines[-1]) - old_column
    if shift < 0:
        return text[:start] + replacement + " " * -shift + text[end:]
    for k in range(1, continued + 1):
        below[k] = " " * shift + below[k]
    return text[:start] + replacement + after + "\n".join(below)


def _comments(text: str) -> list[str]:
    return [c.text for c in parse_text(text).comments]


def _confirm(source: SourceFile, text: str, result: CompileResult) -> None:
    """Raise unless ``rac check`` of ``text`` passes and proves what it proved of ``source`` (every fact
    but the synthesis's own): a rewrite that changed the meaning is a bug, and is never written."""
    assert result.synthesis is not None
    expected = tuple(fact for fact in result.proved if fact not in result.synthesis.facts)
    checked = compile_source(SourceFile(source.name, text))
    if not checked.ok or checked.proved != expected:
        raise RuntimeError(f"the tuned text of {source.name} does not check as the parametrised file did "
                           f"(errors: {[d.code for d in checked.diagnostics if d.is_error]}); nothing was written")


def _failed(args: argparse.Namespace, path: Path, result: CompileResult, status: int = EXIT_ERRORS) -> int:
    """Synthesis (or another check) failed: the diagnostics as ``rac check`` prints them; exit ``status``
    (1: the file's errors; 2: it could not be read, in JSON, where standard output carries it)."""
    errors = sum(d.is_error for d in result.diagnostics)
    if args.format == "json":
        print(json_text({"file": str(path), "ok": False, "values": None, "inequalities": None, "sentence": None,
                         "written": None, "diff": [], "diagnostics": _diagnostics_json(result.diagnostics)},
                        indent=2))
        return status
    print(render_text(result.diagnostics, result.sources))
    print()
    print(f"{path}: {errors} error{'s' * (errors != 1)}; nothing was tuned or written")
    return EXIT_ERRORS


def _horizons(args: argparse.Namespace, source: SourceFile, node: ast.Automaton) -> int:
    """``--horizon``: synthesise at each horizon, print the rows as they come, then the formulas; exit 1
    when no horizon has a value."""
    path: Path = args.file
    plain = compile_source(source, analyse=False)  # the sample period, without running any check
    if plain.automaton is None and not node.of(ast.HorizonDecl) and node.of(ast.SampleDecl):
        # --horizon gives the horizon the file leaves out (each row writes it after `sample every`):
        # read the period at a horizon of one period; on other errors, show the file's own.
        inserted = compile_source(SourceFile(source.name, at_horizon(source, node, None)), analyse=False)
        plain = inserted if inserted.automaton is not None else plain
    if plain.automaton is None:
        return _failed(args, path, plain)
    period = plain.automaton.period
    for horizon in args.horizon:
        if (horizon / period).denominator != 1:
            return _refused(args, path, usage_error(
                f"--horizon: {exact_decimal(horizon)} s is not a whole number of sample periods of {path} "
                f"(sample every {exact_decimal(period) or period} s)"))
    names = [p.name for p in plain.automaton.parameters]
    text = args.format == "text"
    if text:
        print(f"{path}: the synthesised value of each parameter at each horizon H (seconds)")
        print("| H (s) | " + " | ".join(names) + " | set |")
        print("| --- | " + " | ".join("---" for _ in names) + " | --- |", flush=True)
    rows: list[_Row] = []
    try:
        with interrupts_as_such():
            for k, horizon in enumerate(args.horizon):
                if text and sys.stderr.isatty():
                    print(f"\rsynthesising at H = {exact_decimal(horizon)} s ({k + 1}/{len(args.horizon)}) ...",
                          end="", file=sys.stderr, flush=True)
                result = _synthesised(SourceFile(source.name, at_horizon(source, node, horizon)), args,
                                      f"synthesising at H = {exact_decimal(horizon)} s ({k + 1}/{len(args.horizon)})")
                row = _Row(horizon, result.synthesis if result.ok else None,
                           tuple(sorted((d for d in result.diagnostics if d.is_error), key=sort_key)))
                rows.append(row)
                if text:
                    if sys.stderr.isatty():
                        print("\r\033[K", end="", file=sys.stderr, flush=True)
                    print(_row_text(row, names), flush=True)
    except KeyboardInterrupt:  # Ctrl-C or SIGTERM: the horizons synthesised stand (--format json dropped them)
        return _horizons_stopped(args, path, rows)
    fits = {name: fit_line([(r.horizon, r.synthesis.value(name)) for r in rows if r.synthesis is not None])
            for name in names}
    # One parameter's synthesised value is the least of its set; several are a chosen point of theirs.
    relation = ">=" if len(names) == 1 else "="
    # No horizon with a value is a failed synthesis, like `rac tune` on the file itself: exit 1.
    found = any(r.synthesis is not None for r in rows)
    if not text:
        print(json_text({"file": str(path), "ok": found, "written": None, "horizons": [_row_json(r) for r in rows],
                         "formulas": [_fit_json(name, relation, fit) for name, fit in fits.items()]}, indent=2))
        return EXIT_OK if found else EXIT_ERRORS
    for name, fit in fits.items():
        print(_fit_text(name, relation, fit))
    return EXIT_OK if found else EXIT_ERRORS


def _horizons_stopped(args: argparse.Namespace, path: Path, rows: list[_Row]) -> int:
    """``--horizon`` stopped by Ctrl-C or SIGTERM after ``rows``: under ``--format json`` the document with them
    (``"interrupted": true``, no formula: the horizons left could break any line), as text the rows printed
    already; exit 130 (SIGTERM: 143, as :func:`rac.cli.main.main` turns it)."""
    if sys.stderr.isatty():
        print("\r\033[K", end="", file=sys.stderr, flush=True)
    if args.format == "json":
        print(json_text({"file": str(path), "ok": False, "written": None, "horizons": [_row_json(r) for r in rows],
                         "formulas": [], "interrupted": True}, indent=2))
    where = "above" if args.format == "text" else "in the JSON document"
    n = len(rows)
    print(f"rac tune: {how_stopped()}; {counted(n, 'horizon')} synthesised before it "
          f"({where if n else 'none'}; no formula)", file=sys.stderr)
    return EXIT_INTERRUPTED


def _row_text(row: _Row, names: list[str]) -> str:
    if row.synthesis is None:
        return f"| {exact_decimal(row.horizon)} | " + " | ".join("none" for _ in names) + f" | {_reason(row)} |"
    held = " and ".join(row.synthesis.inequalities) or "every value in the bounds"
    return (f"| {exact_decimal(row.horizon)} | " + " | ".join(_value_text(v) for _, v in row.synthesis.values)
            + f" | {held} |")


def _reason(row: _Row) -> str:
    """The errors of a row without values, short: the first one's code, and the others' (or its own)
    message up to its details (``E0406 (E0501: reward `sa` overflows int32 at base 10, exponent 4)``)."""
    first, *others = row.errors or (None,)
    if first is None:
        return "no values"
    if not others:
        return _headline(first)
    return f"{first.code} ({'; '.join(_headline(d) for d in others)})"


def _headline(diagnostic: Diagnostic) -> str:
    """``CODE: message`` without the details after the message's first colon, unless what precedes it
    is too short to say anything (E0407's ``not yet: parameter `P` cannot be synthesised here: ...``
    keeps its second part: ``not yet`` alone named neither the parameter nor the reason)."""
    parts = diagnostic.message.split(": ")
    head = parts[0] if len(parts[0].split()) > 2 else ": ".join(parts[:2])
    return f"{diagnostic.code}: {head}"


def _fit_text(name: str, relation: str, fit: Fit) -> str:
    horizons = ", ".join(exact_decimal(h) or str(h) for h, _ in fit.points)
    if fit.linear:
        return (f"{name} {relation} {formula_text(fit)} (H the horizon in seconds): checked against "
                f"{len(fit.points)} horizons ({horizons})")
    if fit.off is not None:
        (h1, _), (h2, _) = fit.points[:2]
        h, value, predicted = fit.off
        return (f"{name}: not linear in the horizon: the line through H = {exact_decimal(h1)} and "
                f"H = {exact_decimal(h2)} gives {_value_text(predicted)} at H = {exact_decimal(h)}, where the "
                f"value is {_value_text(value)} (no formula)")
    if not fit.points:
        return f"{name}: no horizon has a value (no formula)"
    count = len(fit.points)
    return (f"{name}: a value at {count} horizon{'s' * (count != 1)} only ({horizons}): a line through 2 points "
            "proves nothing (no formula; give at least 3 horizons that have a value)")


def _value_text(value: Fraction) -> str:
    """An exact value for reading: an integer, or ``a / b (≈ decimal)``."""
    return exact_text(value) if value.denominator == 1 else f"{exact_text(value)} (~{float(value):.6g})"


def _number_json(value: Fraction) -> dict[str, object]:
    return {"exact": exact_text(value).replace(" ", ""), "float": float(value)}


def _values_json(synthesis: Synthesised) -> dict[str, object]:
    return {"values": [{"name": name, **_number_json(value)} for name, value in synthesis.values],
            "inequalities": list(synthesis.inequalities)}


def _diagnostics_json(diagnostics: tuple[Diagnostic, ...]) -> list[dict[str, object]]:
    return [d.to_json() for d in sorted(diagnostics, key=sort_key)]


def _row_json(row: _Row) -> dict[str, object]:
    found: dict[str, object] = ({"values": None, "inequalities": None, "sentence": None}
                                if row.synthesis is None else
                                {**_values_json(row.synthesis), "sentence": row.synthesis.sentence})
    return {"horizon": exact_decimal(row.horizon), **found,
            "error": None if row.synthesis is not None else {"codes": [d.code for d in row.errors],
                                                             "reason": _reason(row)}}


def _fit_json(name: str, relation: str, fit: Fit) -> dict[str, object]:
    linear = fit.linear
    return {"parameter": name, "relation": relation, "linear": linear,
            "formula": f"{name} {relation} {formula_text(fit)}" if linear else None,
            "slope": None if fit.slope is None else _number_json(fit.slope),
            "intercept": None if fit.intercept is None else _number_json(fit.intercept),
            "checked": len(fit.points) if linear else 0,
            "points": [{"horizon": exact_decimal(h), "value": _number_json(v)} for h, v in fit.points],
            "text": _fit_text(name, relation, fit)}
