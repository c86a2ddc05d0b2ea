"""Progress for long engine work (exploration, simulation batches, learning), on stderr.

On a terminal a :class:`Progress` is a tqdm bar; ``enabled=True`` forces it, ``enabled=False``
silences it. When stderr is not a terminal (CI logs, ``nohup``, a pipe) a :class:`Heartbeat` prints
one plain line every few seconds instead — the phase, what every :class:`Progress` counted so far,
its rate and the time elapsed — so a long command is never silent::

    rac verify: Qd: strategy safe = control: A[] !collide() && !offroad(); 1.2 M states (412 k/s); 12 s

Example::

    from rac.engine.explore import explore
    from rac.output.progress import Progress, explore_callback

    with Progress(desc="exploring") as bar:
        graph = explore(data, progress=explore_callback(bar))
"""

from __future__ import annotations

import math
import os
import sys
import threading
import time
from collections.abc import Callable
from types import TracebackType
from typing import Any, TextIO

from tqdm import tqdm

__all__ = ["Heartbeat", "Progress", "explore_callback", "notice", "simulate_callback"]


class Progress:
    """A tqdm bar on stderr that is only created when it will be shown.

    ``total`` None gives a counter without a percentage (tqdm still shows the rate, e.g. "states/s").
    ``enabled`` None shows the bar when ``file`` (default: the current ``sys.stderr``) is a TTY.
    ``n`` counts updates whether or not the bar is shown.

    Example::

        with Progress(total=100, desc="simulating", unit="runs") as bar:
            for run in range(100):
                ...
                bar.update()
                bar.set_postfix(below=3)
    """

    def __init__(self, total: int | None = None, desc: str = "", unit: str = "states", enabled: bool | None = None,
                 *, file: TextIO | None = None) -> None:
        # sys.stderr is looked up now, not at import time, so pytest's capture and redirections apply
        stream = sys.stderr if file is None else file
        if enabled is None:
            isatty = getattr(stream, "isatty", None)
            enabled = bool(isatty and isatty())
        self.enabled: bool = enabled
        self.n: int = 0
        self.unit, self.desc = unit, desc
        # a disabled bar never touches tqdm: no output, no monitor thread, no cost per update
        self._bar: tqdm | None = None
        if enabled:
            # tqdm glues the unit to the number ("13.3kstates"); the leading space reads "13.3k states/s".
            # Scaled counts ("13.3k") only where they run large: tqdm shows a scaled 3 of 8 tasks as "3.00/8.00"
            self._bar = tqdm(total=total, desc=desc, unit=f" {unit}", unit_scale=total is None or total >= 1000,
                             file=stream, dynamic_ncols=True, leave=False)

    def update(self, n: int = 1) -> None:
        """Advance the bar by ``n`` (and tell the active :class:`Heartbeat`, if any)."""
        self.n += n
        if self._bar is not None:
            self._bar.update(n)
        beat = Heartbeat.active
        if beat is not None:
            beat.count(self.n, self.unit, self.desc)

    def set_postfix(self, **values: Any) -> None:
        """Show ``key=value`` pairs after the bar (e.g. the current layer); ignored when disabled."""
        if self._bar is not None:
            self._bar.set_postfix(values, refresh=False)

    def close(self) -> None:
        """Remove the bar from the terminal (idempotent)."""
        if self._bar is not None:
            self._bar.close()
            self._bar = None

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self.close()


def explore_callback(bar: Progress) -> Callable[[int, int, int], None]:
    """The ``progress(layer, frontier_size, total_states)`` callback of :func:`rac.engine.explore.explore`
    that advances ``bar`` to the number of states found so far (so tqdm shows states and states/s)
    and shows the layer and the frontier size after it.

    Example::

        with Progress(desc="exploring", unit="states") as bar:
            graph = explore(data, progress=explore_callback(bar))
    """

    def progress(layer: int, frontier_size: int, total_states: int) -> None:
        bar.set_postfix(layer=layer, frontier=frontier_size)
        bar.update(total_states - bar.n)  # explore reports a running total, the bar wants increments

    return progress


def simulate_callback(bar: Progress, check: Callable[[int, int], None] | None = None) -> Callable[[int, int], None]:
    """The ``progress(sample, horizon)`` callback of :func:`rac.engine.simulate.simulate` that advances ``bar``
    to the samples simulated so far, then calls ``check(sample, horizon)`` (a time limit's, which may raise).

    Example::

        with Progress(total=samples, desc="simulating", unit="samples") as bar:
            runs = simulate(data, runs=100, horizon_samples=samples, progress=simulate_callback(bar))
    """

    def progress(sample: int, horizon: int) -> None:
        bar.update(sample - bar.n)  # simulate reports the sample reached, the bar wants increments
        if check is not None:
            check(sample, horizon)

    return progress


def notice(command: str = "rac", file: TextIO | None = None) -> Callable[[str], None]:
    """A callback printing each word it hears as one line on stderr (``rac check: loading ...``): for
    work that cannot count its own progress, such as a scenario's load (the ``model`` layer prints
    nothing itself). The word is the phase of the active :class:`Heartbeat` as well, so that its
    lines say what a long load is doing."""

    def say(text: str) -> None:
        print(f"{command}: {text}", file=file or sys.stderr, flush=True)
        if Heartbeat.active is not None:
            Heartbeat.active.phase(text)

    return say


#: The seconds between heartbeat lines without ``RAC_PROGRESS_INTERVAL``, and the most it may set.
DEFAULT_INTERVAL, MAX_INTERVAL = 10.0, 86400.0


def progress_interval() -> float:
    """``RAC_PROGRESS_INTERVAL`` in seconds, or the default when it is unset; a value that is not a
    positive number of seconds up to a day is said once on standard error and the default used (a progress
    setting never stops a command, nor floods its log)."""
    text = os.environ.get("RAC_PROGRESS_INTERVAL", "").strip()
    if not text:
        return DEFAULT_INTERVAL
    try:
        value = float(text)
    except ValueError:
        value = math.nan
    if not 0 < value <= MAX_INTERVAL:  # NaN too; 0 would print without pause
        global _SAID_INTERVAL
        if not _SAID_INTERVAL:
            _SAID_INTERVAL = True
            print(f"rac: RAC_PROGRESS_INTERVAL={text!r} is not a positive number of seconds up to {MAX_INTERVAL:g}; "
                  f"progress lines come every {DEFAULT_INTERVAL:g} s", file=sys.stderr)
        return DEFAULT_INTERVAL
    return value


_SAID_INTERVAL = False


class Heartbeat:
    """Plain progress lines for a stream that is not a terminal: every ``interval`` seconds (default
    ``RAC_PROGRESS_INTERVAL``, else 10) while the command runs, ``COMMAND: PHASE; COUNT UNIT (RATE/s); ELAPSED``.

    ``enabled`` None: on when ``file`` (default: the current ``sys.stderr``) is not a TTY. While a
    heartbeat is entered it is :attr:`active`, and every :class:`Progress` reports its count to it.

    Example::

        with Heartbeat("rac experiment") as beat:
            beat.phase("learning, seed 1")
            ...
    """

    #: The heartbeat entered last and not yet left (the one :meth:`Progress.update` reports to).
    active: Heartbeat | None = None

    def __init__(self, command: str, *, interval: float | None = None, enabled: bool | None = None,
                 file: TextIO | None = None) -> None:
        if interval is None:  # RAC_PROGRESS_INTERVAL: seconds between lines (default 10)
            interval = progress_interval()
        self.stream = sys.stderr if file is None else file
        if enabled is None:
            isatty = getattr(self.stream, "isatty", None)
            enabled = not (isatty and isatty())
        self.enabled = enabled
        self.command, self.interval = command, interval
        self._phase = ""
        self._count: tuple[int, str, float] | None = None  # count, unit, when the phase's counting began
        self._start = time.monotonic()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._outer: Heartbeat | None = None

    def phase(self, text: str) -> None:
        """What the command is doing now (a query, a setting, a seed)."""
        self._phase, self._count = text, None

    def count(self, n: int, unit: str, what: str = "") -> None:
        """How much of the phase is done (``n`` states, episodes, runs; ``what`` names the work)."""
        # a count that starts again (the next batch of a query's runs) has a rate of its own
        going_on = self._count is not None and self._count[1] == unit and n >= self._count[0]
        since = self._count[2] if going_on and self._count is not None else time.monotonic()
        self._count = (n, unit, since)
        if what and not self._phase:
            self._phase = what

    def line(self) -> str:
        """The line printed now."""
        now = time.monotonic()
        parts = [self._phase or "working"]
        if self._count is not None:
            n, unit, since = self._count
            rate = n / max(now - since, 1e-9)
            parts.append(f"{_short(n)} {unit.strip()} ({_short(rate)}/s)")
        return f"{self.command}: {'; '.join(parts)}; {now - self._start:.0f} s"

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            print(self.line(), file=self.stream, flush=True)

    def __enter__(self) -> Heartbeat:
        self._outer, Heartbeat.active = Heartbeat.active, self
        if self.enabled:
            self._thread = threading.Thread(target=self._run, name="rac-heartbeat", daemon=True)
            self._thread.start()
        return self

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        Heartbeat.active = self._outer


def _short(value: float) -> str:
    """``1234567`` -> ``1.2 M``; small numbers as they are."""
    for unit, scale in (("G", 1e9), ("M", 1e6), ("k", 1e3)):
        if value >= scale:
            return f"{value / scale:.3g} {unit}"
    return f"{value:.3g}" if value != int(value) else str(int(value))
