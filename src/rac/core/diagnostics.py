"""Diagnostics as data, and the one renderer that prints them.

Every stage reports problems as :class:`Diagnostic` values; nothing prints on
its own. The CLI renders them as text (``file:line:col: error[code]: ...`` with
the source line and a caret) or as JSON with the same fields.
"""

from __future__ import annotations

import json
import re
import unicodedata
from collections.abc import Callable, Iterable, Mapping
from dataclasses import dataclass, field
from decimal import Context, Decimal
from enum import Enum
from fractions import Fraction

from rac.core.source import SourceFile, Span

#: The code of a check that stopped at its limit, neither proved nor refuted: the file is undecided
#: (``rac check`` exits 4 when no file has an error, as ``rac verify`` does for an undecided query).
UNFINISHED = "W0405"
#: The code of the incentive checks left undone (an update that is not a translation, or too long a
#: horizon); its ``data["required"]`` lists those a ``require`` asks for, which it leaves undecided.
INCENTIVES_UNDONE = "W1008"


class Severity(str, Enum):
    ERROR = "error"
    WARNING = "warning"


@dataclass(frozen=True)
class Note:
    """A secondary message, optionally pointing at another place."""

    message: str
    span: Span | None = None


@dataclass(frozen=True)
class Diagnostic:
    """One finding: a code (documented in docs/diagnostics.md), where, what, and what to do."""

    code: str
    severity: Severity
    message: str
    span: Span | None
    notes: tuple[Note, ...] = ()
    hints: tuple[str, ...] = ()
    #: Structured extra data (witness valuations, counterexample runs) for --format json.
    data: Mapping[str, object] = field(default_factory=dict, compare=False)

    @property
    def is_error(self) -> bool:
        return self.severity is Severity.ERROR

    def to_json(self) -> dict[str, object]:
        return {
            "code": self.code,
            "severity": self.severity.value,
            "message": self.message,
            "span": self.span.to_json() if self.span else None,
            "notes": [
                {"message": n.message, "span": n.span.to_json() if n.span else None}
                for n in self.notes
            ],
            "hints": list(self.hints),
            "data": dict(self.data),
        }


@dataclass(frozen=True)
class Fact:
    """What a check proved, the counterpart of a :class:`Diagnostic`: the ``check`` that proved it
    (one of :data:`FACT_CHECKS`), the sentence ``rac check`` prints, and its numbers in ``data`` for
    ``--format json``."""

    check: str
    message: str
    data: Mapping[str, object] = field(default_factory=dict, compare=False)

    def __post_init__(self) -> None:
        if self.check not in FACT_CHECKS:
            raise ValueError(f"unknown check {self.check!r}: one of {', '.join(FACT_CHECKS)}")

    def __str__(self) -> str:
        return self.message

    def to_json(self) -> dict[str, object]:
        return {"check": self.check, "message": self.message, "data": dict(self.data)}


#: The checks that state facts: determinism, the priority order's P1 and P2 (``priority``: none declared),
#: the int32 range of the rewards, the parameters' synthesis, the scenario's load, and issue 25's
#: incentives: the risk tolerance p* and the three loophole checks (``rac.ir.REQUIREMENT_CHECKS``);
#: ``P2-discounted``: P2 of the discounted return (``rac check --discount``).
FACT_CHECKS = ("determinism", "priority", "P1", "P2", "P2-discounted", "range", "synthesis", "scenario", "risk",
               "ending_early_never_pays", "goal_earlier_never_pays_less", "stalling_never_pays")


def error(code: str, message: str, span: Span | None, *, notes: Iterable[Note | str] = (),
          hints: Iterable[str] = (), data: Mapping[str, object] | None = None) -> Diagnostic:
    """Build an error diagnostic; plain strings in ``notes`` become span-less notes."""
    return _make(Severity.ERROR, code, message, span, notes, hints, data)


def warning(code: str, message: str, span: Span | None, *, notes: Iterable[Note | str] = (),
            hints: Iterable[str] = (), data: Mapping[str, object] | None = None) -> Diagnostic:
    """Build a warning diagnostic."""
    return _make(Severity.WARNING, code, message, span, notes, hints, data)


def _make(severity: Severity, code: str, message: str, span: Span | None,
          notes: Iterable[Note | str], hints: Iterable[str],
          data: Mapping[str, object] | None) -> Diagnostic:
    return Diagnostic(
        code=code,
        severity=severity,
        message=message,
        span=span,
        notes=tuple(n if isinstance(n, Note) else Note(n) for n in notes),
        hints=tuple(hints),
        data=dict(data or {}),
    )


def short_number(value: Fraction, digits: int = 6) -> str:
    """A rational as a short decimal for messages; a trailing ``…`` marks a rounded value."""
    if value.denominator == 1 and abs(value.numerator) < 10**16:
        return str(value.numerator)
    if value.denominator == 1:  # a huge integer: 1E+308, not 309 digits
        text = str(Context(prec=digits).create_decimal(value.numerator).normalize()).replace("E+", "e")
        return text if Fraction(text) == value else f"{text}…"
    if Fraction(1, 10**12) <= abs(value) <= 10**15:
        text = f"{float(value):.{digits}g}"
    else:  # beyond the range floats print well (or at all): decimal arithmetic never overflows
        text = str(Context(prec=digits).divide(Decimal(value.numerator), Decimal(value.denominator)).normalize())
        text = text.replace("E+", "e").replace("E", "e")  # 1e-300, as the huge integers above and .ra files write it
    return text if Fraction(text) == value else f"{text}…"


def short_count(count: int) -> str:
    """A count for messages: with thousands separators (``150,000``), or as :func:`short_number` when
    huge (``1e309``, not 103 groups of digits)."""
    return f"{count:,}" if abs(count) < 10**16 else short_number(Fraction(count))


def counted(count: int, noun: str, plural: str | None = None) -> str:
    """``count`` and its noun for messages: ``1 run``, ``2,000 runs`` (``plural`` where adding ``s`` is wrong)."""
    return f"{short_count(count)} {noun if count == 1 else plural or noun + 's'}"


def _restored(kind: type[RacError], args: tuple[object, ...], state: dict[str, object]) -> RacError:
    """An exception of rac's rebuilt from its ``args`` and attributes without calling its ``__init__``,
    whose parameters are the failure's parts, not its message (what :meth:`RacError.__reduce__` hands pickle)."""
    error = kind.__new__(kind, *args)
    Exception.__init__(error, *args)
    error.__dict__.update(state)
    return error


def _copy_into(error: BaseException, original: BaseException) -> None:
    """``error`` made the same failure as ``original``: its ``args`` and attributes."""
    Exception.__init__(error, *original.args)
    error.__dict__.update(original.__dict__)


class RacError(Exception):
    """The root of rac's own exceptions. ``diagnostic``, when set, is the failure in the user's words
    (a code of docs/checks.md, where, and what to do): the ``rac`` command renders it through the one
    renderer, like the checker's findings. Subclasses keep a builtin base where callers expect one
    (``class ScenarioError(RacError, ValueError)``).

    Every one of them survives another process: ``pickle`` rebuilds it from its ``args`` and attributes
    (not through an ``__init__`` that takes the failure's parts), and ``type(error)(error)`` is the same
    failure again, which is how gymnasium's ``AsyncVectorEnv`` re-raises a worker's exception (a
    ``CheckError`` of a scene checked in a worker said ``TypeError: 'CheckError' object is not iterable``)."""

    #: The failure as the user reads it; None for a failure that only rac itself handles.
    diagnostic: Diagnostic | None = None

    def __init_subclass__(cls, **kwargs: object) -> None:
        super().__init_subclass__(**kwargs)
        own = cls.__dict__.get("__init__")
        if own is None:
            return

        def __init__(self: RacError, *args: object, **named: object) -> None:
            if len(args) == 1 and not named and type(args[0]) is type(self):
                _copy_into(self, args[0])  # type(error)(error): the same failure
            else:
                own(self, *args, **named)

        __init__.__doc__, __init__.__wrapped__ = own.__doc__, own  # type: ignore[attr-defined]
        cls.__init__ = __init__  # type: ignore[method-assign]

    def __init__(self, *args: object, diagnostic: Diagnostic | None = None) -> None:
        if len(args) == 1 and diagnostic is None and type(args[0]) is type(self):
            _copy_into(self, args[0])  # type: ignore[arg-type]
            return
        super().__init__(*(args or ((diagnostic.message,) if diagnostic is not None else ())))
        if diagnostic is not None:
            self.diagnostic = diagnostic

    def __reduce__(self) -> tuple[object, ...]:
        """For pickle and copy: rebuilt from ``args`` and the attributes (:func:`_restored`)."""
        return _restored, (type(self), self.args, dict(self.__dict__))


class RacValueError(RacError, ValueError):
    """A value rac cannot use as given, met after the checker: a file without a ``model`` block where
    one is needed, a shield or strategy file of another model, a horizon that is no whole number of
    samples, a query the engine does not answer. The user's to change, not a bug in rac; a
    ``ValueError`` as before."""


class CheckError(RacError):
    """Raised by :func:`rac.load` when a file has errors; carries every diagnostic."""

    def __init__(self, diagnostics: Iterable[Diagnostic], sources: Mapping[str, SourceFile] | None = None):
        self.diagnostics = tuple(diagnostics)
        self.sources = dict(sources or {})
        super().__init__(render_text(self.diagnostics, self.sources))

    def __reduce__(self) -> tuple[type[CheckError], tuple[tuple[Diagnostic, ...], dict[str, SourceFile]]]:
        """For pickle and copy: rebuilt from its diagnostics and sources (``args`` holds only the rendered
        text), so a check failing in a worker process (``SubprocVecEnv``, a process pool) reaches the parent."""
        return type(self), (self.diagnostics, self.sources)

    def brief(self) -> str:
        """The first diagnostic's message and first hint on one line, for an option's value (an
        expression given on the command line has no file to show it in)."""
        first = self.diagnostics[0]
        return first.message + (f" ({first.hints[0]})" if first.hints else "")


class RacCheckWarning(RacError, UserWarning):
    """The warnings of ``rac check`` (W codes) about a file loaded from Python (:func:`rac.load`, the
    wrappers given a path), where no report is printed; filter them by this category."""


def leaves_undecided(diagnostic: Diagnostic) -> bool:
    """Whether ``diagnostic`` leaves a verdict open: a check stopped at its limit (W0405), or a check a
    ``require`` asks for that could not be made (W1008 naming it). Such a file without errors is
    undecided: ``rac check`` exits 4, never 0."""
    return diagnostic.code == UNFINISHED or (
        diagnostic.code == INCENTIVES_UNDONE and bool(diagnostic.data.get("required")))


def check_warning_text(diagnostics: Iterable[Diagnostic]) -> str | None:
    """One line per warning among ``diagnostics`` (``file:line: W0302 message``), None without any."""
    found = [d for d in diagnostics if d.severity is Severity.WARNING]
    if not found:
        return None
    lines = []
    for d in sorted(found, key=sort_key):
        where = f"{d.span.file}:{d.span.line}: " if d.span is not None else ""
        lines.append(f"  {where}{d.code} {d.message}")
    return (f"rac check found {len(found)} warning{'s' if len(found) != 1 else ''} "
            "(`rac check FILE` prints them with their notes and hints):\n" + "\n".join(lines))


def sort_key(d: Diagnostic) -> tuple[str, int, int, str]:
    if d.span is None:
        return ("", 0, 0, d.code)
    return (d.span.file, d.span.line, d.span.column, d.code)


#: Source lines longer than this are shown as a window around the span (a generated file may have
#: lines of megabytes).
MAX_SHOWN_LINE = 120


def _cells(text: str) -> int:
    """The terminal columns ``text`` takes: two for a wide character (CJK), none for a combining mark, so
    that the caret stands under its span on a line whose comment holds such characters."""
    return sum(0 if unicodedata.combining(ch) else 2 if unicodedata.east_asian_width(ch) in "WF" else 1
               for ch in text)


#: A lone surrogate: in a file name that is not UTF-8, an undecodable byte (U+DC80..U+DCFF, ``os.fsdecode``).
_SURROGATE = re.compile("[\ud800-\udfff]")


def display_text(text: str) -> str:
    """``text`` as rac shows it, in text and in JSON: valid Unicode. A file name that is not UTF-8 reaches
    rac (``os.fsdecode``) with each undecodable byte as a lone surrogate, which a strict UTF-8 stream
    refuses (an internal error) and strict JSON readers reject (``"\\udcff"``); it is shown as that byte's
    escape, ``\\xff``, as ``os.fsencode`` then ``backslashreplace`` writes it. Any other lone surrogate is
    shown as ``\\uXXXX``."""
    if text.isascii():
        return text
    return _SURROGATE.sub(lambda match: _escape(match.group()), text)


def _escape(surrogate: str) -> str:
    code = ord(surrogate)
    return f"\\x{code - 0xDC00:02x}" if 0xDC80 <= code <= 0xDCFF else f"\\u{code:04x}"


def json_text(document: object, *, indent: int | None = 2, default: Callable[[object], object] | None = None) -> str:
    """``document`` as the JSON text a command prints (``json.dumps`` with ``indent`` and ``default``), every
    string (keys too) shown by :func:`display_text`, so that the output is valid UTF-8 JSON whatever the
    file names."""

    def shown(value: object) -> object:
        if isinstance(value, str):
            return display_text(value)
        if value is None or isinstance(value, bool | int | float):
            return value
        if isinstance(value, Mapping):
            return {shown(key) if isinstance(key, str) else key: shown(item) for key, item in value.items()}
        if isinstance(value, list | tuple):
            return [shown(item) for item in value]
        return value if default is None else shown(default(value))

    return json.dumps(shown(document), indent=indent)


def _printable(text: str) -> str:
    """``text`` with its control characters (but newlines and tabs) written as escapes (``\\x1b``): a
    message may quote the user's text, e.g. a file name, and a raw escape character would garble or
    drive the terminal. A file name's undecodable bytes are shown as :func:`display_text` shows them."""
    text = display_text(text)
    if text.isprintable():
        return text
    return "".join(ch if ch.isprintable() or ch in "\n\t" else repr(ch)[1:-1] for ch in text)


def _render_one(d: Diagnostic, sources: Mapping[str, SourceFile]) -> str:
    where = f"{d.span}: " if d.span else ""
    lines = [_printable(f"{where}{d.severity.value}[{d.code}]: {d.message}")]
    source = sources.get(d.span.file) if d.span else None
    gutter = 0
    if d.span is not None and source is not None:
        # Control characters would garble a terminal: show them as U+FFFD, one column each.
        text = "".join(ch if ch.isprintable() or ch == "\t" else "\ufffd" for ch in source.line_text(d.span.line))
        gutter = len(str(d.span.line))
        pad = " " * gutter
        # The caret covers the span on its first line (at least one character).
        last = d.span.end_column if d.span.end_line == d.span.line else len(text) + 1
        first = d.span.column
        if len(text) > MAX_SHOWN_LINE:  # a window of the line around the span's start, marked with …
            start = max(0, first - 1 - 40)
            end = min(len(text), start + MAX_SHOWN_LINE)
            head, tail = ("…" if start else ""), ("…" if end < len(text) else "")
            text = head + text[start:end] + tail
            first = first - start + len(head)
            last = min(last - start + len(head), len(head) + (end - start) + 1)
        width = max(1, _cells(text[first - 1:last - 1]))
        prefix = "".join(ch if ch == "\t" else " " * _cells(ch) for ch in text[: first - 1])
        lines += [
            f"{pad} |",
            f"{d.span.line} | {text}",
            f"{pad} | {prefix}{'^' * width}",
        ]
    pad = " " * gutter
    for note in d.notes:
        body = _printable(note.message).replace("\n", "\n" + pad + "         ")
        where = _printable(f" (at {note.span})") if note.span else ""
        lines.append(f"{pad} = note: {body}{where}")
    for hint in d.hints:
        lines.append(f"{pad} = hint: " + _printable(hint).replace("\n", "\n" + pad + "         "))
    return "\n".join(lines)


def render_text(diagnostics: Iterable[Diagnostic], sources: Mapping[str, SourceFile]) -> str:
    """Render diagnostics as the human-readable text the CLI prints."""
    return "\n\n".join(_render_one(d, sources) for d in sorted(diagnostics, key=sort_key))


def render_json(diagnostics: Iterable[Diagnostic]) -> str:
    """Render diagnostics as a JSON array with the same data as :func:`render_text`."""
    return json_text([d.to_json() for d in sorted(diagnostics, key=sort_key)])
