"""Progress bars for long engine work (exploration, simulation batches), on stderr via tqdm.

A bar shows only when stderr is a terminal, so piped output, ``--format json`` and tests stay
clean; ``enabled=True`` forces it, ``enabled=False`` silences it.

Example::

    from rac.engine.explore import explore
    from rac.output.progress import Progress, explore_callback

    with Progress(desc="exploring") as bar:
        graph = explore(data, progress=explore_callback(bar))
"""

from __future__ import annotations

import sys
from collections.abc import Callable
from types import TracebackType
from typing import Any, TextIO

from tqdm import tqdm

__all__ = ["Progress", "explore_callback"]


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
        # a disabled bar never touches tqdm: no output, no monitor thread, no cost per update
        self._bar: tqdm | None = None
        if enabled:
            # tqdm glues the unit to the number ("13.3kstates"); the leading space reads "13.3k states/s"
            self._bar = tqdm(total=total, desc=desc, unit=f" {unit}", unit_scale=True, file=stream,
                             dynamic_ncols=True, leave=False)

    def update(self, n: int = 1) -> None:
        """Advance the bar by ``n``."""
        self.n += n
        if self._bar is not None:
            self._bar.update(n)

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
