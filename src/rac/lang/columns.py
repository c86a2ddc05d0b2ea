"""Column layout for runs of similar lines: the alignment of ``rac fmt`` (:mod:`rac.lang.format`).

A line is a row of cells (``["edge * -> Unsafe", "when isClose", "do sa -= 100"]``); the i-th cells
of the rows of a run start in one column. The formatter decides what the cells and the runs are;
this module only pads.
"""

from __future__ import annotations

from collections.abc import Sequence

__all__ = ["align_cells", "comment_column"]


def align_cells(rows: Sequence[Sequence[str]]) -> list[str]:
    """Join each row's cells with one space so that the i-th cells of all rows start in one column.

    A column is as wide as its widest cell. An empty cell is padded to its column's width when a
    later cell of its row is not empty, and adds nothing otherwise (no line ends in spaces); a
    column empty in every row takes no room. A single row is its non-empty cells joined by spaces.
    """
    count = max((len(row) for row in rows), default=0)
    widths = [max((len(row[i]) for row in rows if i < len(row)), default=0) for i in range(count)]
    lines: list[str] = []
    for row in rows:
        last = max((i for i, cell in enumerate(row) if cell), default=-1)
        cells = [row[i] if i == last else row[i].ljust(widths[i]) for i in range(last + 1) if widths[i]]
        lines.append(" ".join(cells))
    return lines


def comment_column(widths: Sequence[int], limit: int) -> int | None:
    """The column of the trailing comments of a run of lines whose code is ``widths`` long
    (only the lines that have trailing comments): two spaces after the longest line that is not
    longer than ``limit`` (a longer line keeps its comment two spaces after it, alone); None if
    every line is longer."""
    fitting = [width for width in widths if width <= limit]
    return max(fitting) + 2 if fitting else None
