"""``rac new NAME [--from FILE]``: start a reward automaton from a standard-library file.

The file (default: the standard library's ``driving.ra``; a bare name such as ``speed_limit`` is looked
up in the standard library) is copied to ``NAME.ra``, its automaton renamed to the CamelCase of NAME
when NAME is an identifier; a relative ``scenario`` path of its ``model`` block is rewritten to name the same file
from NAME's folder. An existing file is never overwritten (E0009, exit 2). The ``--from`` file is read as
``rac check`` reads one: no UTF-8 text is E0004 and a syntax error its diagnostic (exit 1, nothing
written), a folder, a FIFO or a device E0008 (exit 2).
"""

from __future__ import annotations

import argparse
import errno
import os
import re
import shlex
import sys
from pathlib import Path

from rac.cli.arguments import DEFAULT_TEMPLATE
from rac.cli.common import EXIT_ERRORS, EXIT_OK, EXIT_USAGE, unreadable, unwritable
from rac.core.diagnostics import Diagnostic, error, render_text
from rac.lang import ast
from rac.lang.parser import ParseFailure, parse_source, parse_text, read_source
from rac.lang.resources import stdlib_file

__all__ = ["camel_case", "new_command", "renamed", "repointed", "template_path"]

_IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def camel_case(name: str) -> str | None:
    """``my_reward`` -> ``MyReward``; None when ``name`` is not an identifier of the language."""
    if not _IDENTIFIER.fullmatch(name):
        return None
    camel = "".join(part[:1].upper() + part[1:] for part in name.split("_") if part)
    return camel or None


def template_path(template: str) -> Path:
    """The file ``--from`` names: an existing path, else a standard-library file (``speed_limit``,
    ``speed_limit.ra`` or ``stdlib/speed_limit.ra``). Raises FileNotFoundError listing the stdlib."""
    path = Path(template)
    if path.exists():
        return path
    if path.parent in (Path("."), Path("stdlib")):  # a stdlib name, wherever rac is installed
        return stdlib_file(path.name if path.suffix == ".ra" else f"{path.name}.ra")
    raise FileNotFoundError(f"no such file: {template}")


def renamed(text: str, name: str) -> str:
    """``text`` with its (first) automaton called ``name``: the declaration and the qualified
    references ``Old.location`` in queries. ``text`` unchanged when it does not parse or the new
    text would not."""
    try:
        automata = parse_text(text).automata
    except ParseFailure:
        return text
    if not automata or automata[0].name.span is None:
        return text
    old, span = automata[0].name.name, automata[0].name.span
    # the declaration and the references `Old.member` the parser found, never a comment's or a
    # scenario path's text that merely reads alike (`scenario "Old.xml"`)
    references = ast.nodes_in(automata, ast.Qualified)
    starts = [span.start, *(q.span.start for q in references if q.scope == old and q.span is not None)]
    result = text
    for start in sorted(set(starts), reverse=True):
        if result[start:start + len(old)] == old:  # the name itself, where the parser saw it
            result = result[:start] + name + result[start + len(old):]
    try:
        parse_text(result)
    except ParseFailure:  # the name is a word the grammar reserves (e.g. a query's `A`)
        return text
    return result


def repointed(text: str, source: Path, target: Path) -> str:
    """``text`` (the file ``source``) as the file ``target``: each relative ``scenario "PATH"`` of a
    ``model`` block rewritten to name the same file from ``target``'s folder (the checker resolves it
    from the folder of the file that writes it). ``text`` unchanged when it does not parse."""
    folder, moved_to = os.path.dirname(source) or ".", os.path.dirname(target) or "."
    if os.path.abspath(folder) == os.path.abspath(moved_to):
        return text
    try:
        automata = parse_text(text).automata
    except ParseFailure:
        return text
    scenarios = [item for automaton in automata for block in automaton.of(ast.ModelDecl)
                 for item in block.of(ast.ModelScenario)]
    for item in sorted(scenarios, key=lambda i: i.span.start if i.span else -1, reverse=True):
        if item.span is None or os.path.isabs(item.path):
            continue
        moved = os.path.relpath(os.path.join(folder, item.path), moved_to)
        written = text[item.span.start:item.span.end]
        quote = written.rindex('"', 0, -1)  # `scenario "PATH"`: the string is the item's last token
        if not {'"', "\n"} & set(moved):  # a string holds neither
            text = text[:item.span.start] + written[:quote] + f'"{moved}"' + text[item.span.end:]
    return text


def _exists(path: Path) -> Diagnostic:
    """E0009: ``rac new`` never overwrites a file."""
    return error("E0009", f"cannot write `{path}`: the file exists", None,
                 hints=["choose another NAME or remove the file; `rac new` never overwrites one"])


def _create(path: Path, text: str) -> None:
    """Write ``text`` to ``path``, a file that must not exist: created exclusively (``O_EXCL``), so that a file
    made there after :func:`new_command` looked (another ``rac new``, an editor saving) is never replaced, as a
    rename would replace it; removed again when the write fails (a full disk, an interrupt): it was this
    command's. ``FileExistsError`` when ``path`` exists."""
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o666)
    try:
        with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as handle:
            handle.write(text)
    except BaseException:
        path.unlink(missing_ok=True)
        raise


def new_command(args: argparse.Namespace) -> int:
    """``rac new NAME --from FILE``: copy, rename, write atomically, say what to run next."""
    stem = Path(args.name).name.removesuffix(".ra")
    if not stem.strip(".") or args.name.endswith(("/", os.sep)):  # "", ".", "..", ".ra", "dir/"
        print(f"rac new: NAME `{args.name}` names no file: give the file's name, e.g. `rac new my_reward` "
              "(writes my_reward.ra)", file=sys.stderr)
        return EXIT_USAGE
    target = Path(args.name if args.name.endswith(".ra") else f"{args.name}.ra")
    try:  # without --from the standard library's file, never a file of that name in the working folder
        source = stdlib_file(DEFAULT_TEMPLATE) if args.template is None else template_path(args.template)
    except FileNotFoundError as exc:
        print(render_text([error("E0008", f"cannot read `{args.template}`: {exc.args[0]}", None,
                                 hints=["pass a .ra file or a standard-library name"])], {}), file=sys.stderr)
        return EXIT_USAGE
    read = None
    try:  # as rac check, fmt and tune read a file: a FIFO or a device is refused, never read to its end
        read = read_source(source)
        # a file that does not parse is no start: its syntax error, as rac check prints it, and no copy
        parse_source(read)
    except OSError as exc:
        print(render_text([unreadable(source, exc)], {}), file=sys.stderr)
        return EXIT_USAGE
    except ParseFailure as failure:  # not UTF-8 text, NUL bytes, too large (E0004/E0005), a syntax error
        shown = read or failure.source  # the text read, for the caret under a syntax error
        print(render_text([failure.diagnostic], {shown.name: shown} if shown else {}), file=sys.stderr)
        return EXIT_ERRORS
    # Windows line ends as \n, as in every file rac writes (read_source keeps them for rac fmt)
    text = read.text.replace("\r\n", "\n")
    try:
        taken = target.exists() or target.is_symlink()
    except OSError as exc:  # a name too long for the file system
        print(render_text([unwritable(target, exc)], {}), file=sys.stderr)
        return EXIT_USAGE
    if taken:
        print(render_text([_exists(target)], {}), file=sys.stderr)
        return EXIT_USAGE
    automaton = camel_case(target.name[:-len(".ra")])
    renamed_text = renamed(text, automaton) if automaton else text
    written = repointed(renamed_text, source, target)
    try:
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
        except FileExistsError:  # a file where NAME's folder goes: not "File exists" of a file that does not
            raise NotADirectoryError(errno.ENOTDIR, os.strerror(errno.ENOTDIR), str(target.parent)) from None
        _create(target, written)
    except FileExistsError:  # made meanwhile (another rac new, an editor): it is someone's, and stays
        print(render_text([_exists(target)], {}), file=sys.stderr)
        return EXIT_USAGE
    except OSError as exc:
        print(render_text([unwritable(target, exc)], {}), file=sys.stderr)
        return EXIT_USAGE
    how = f", automaton {automaton}" if renamed_text != text else ""
    print(f"wrote {target} (from {source}{how})")
    # a command the user can paste: quoted (a space), and not taken for an option (a leading `-`)
    command = str(target)
    print(f"next: rac check {shlex.quote(f'./{command}' if command.startswith('-') else command)}")
    return EXIT_OK
