"""What each reward pays for, side by side: ``python -m rac.studies.incentives FILE.ra ...``.

For every file, the risk tolerance p* with the three returns it weighs, and the verdict of each
loophole check (docs/checks.md), on one row as the file declares its episodes and, when it leaves
the ending to the environment, on a second row as a gymnasium environment would run them: ending
at a collision or at the goal (``episode ends when`` the file's ``collision`` or ``goal`` condition).
Prints one markdown table (docs/stdlib.md shows the stdlib's). Exit 0, or 1 when a file does not
check.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from collections.abc import Sequence
from fractions import Fraction

from rac import ir
from rac.check.analysis.behaviour import input_space
from rac.check.analysis.incentives import Findings, Loophole, Unchecked, analyse
from rac.compiler import compile_file
from rac.core.diagnostics import short_number
from rac.ir.text import format_guard

__all__ = ["COLUMNS", "gym_ending", "main", "row", "rows"]

#: The table's columns, in order.
COLUMNS = ("file", "episodes end", "R_goal", "R_stall", "R_crash", "p*", "ending early never pays",
           "goal earlier never pays less", "stalling never pays")


def gym_ending(automaton: ir.Automaton) -> ir.Automaton | None:
    """The automaton with its episodes ending at a collision or at the goal (None when the file
    declares its own ending, or neither condition)."""
    if automaton.episode_ends is not None:
        return None
    parts = tuple(g for g in (automaton.collision, automaton.goal) if g is not None)
    if not parts:
        return None
    return dataclasses.replace(automaton, episode_ends=parts[0] if len(parts) == 1 else ir.BOr(parts))


def _findings(automaton: ir.Automaton) -> Findings | Unchecked | None:
    space, _ = input_space(automaton)
    if space is None:
        return None
    return analyse(automaton, space)


def _verdict(found: Findings | Unchecked | None, check: str) -> str:
    if found is None:
        return "—"
    if isinstance(found, Unchecked):
        return f"not checked: {found.reason}"
    if check not in found.verdicts:
        return "—"
    loophole: Loophole | None = found.verdicts[check]
    if loophole is None:
        return "holds"
    at = (f"samples {loophole.other_sample} and {loophole.sample}" if loophole.other_sample
          else f"sample {loophole.sample}")
    return f"**fails** by {short_number(loophole.delta)} ({at})"


def _number(value: Fraction | None) -> str:
    return "—" if value is None else short_number(value)


def _ending(automaton: ir.Automaton) -> str:
    if automaton.episode_ends is None:
        return "at the horizon"
    return f"when {format_guard(automaton.episode_ends)}, else at the horizon"


def row(path: str, automaton: ir.Automaton) -> tuple[str, ...]:
    """One file's cells as it declares its episodes, in the order of :data:`COLUMNS`."""
    found = _findings(automaton)
    incentives = found.incentives if isinstance(found, Findings) else None
    returns: tuple[str, ...]
    if incentives is None:
        returns = ("—", "—", "—")
        p = "— (no `goal when`)" if automaton.goal is None else "—"
    else:
        returns = tuple(_number(None if run is None else run.value)
                        for run in (incentives.goal, incentives.stall, incentives.crash))
        p = _number(incentives.p_star) if incentives.p_star is not None else f"undefined: {incentives.p_note}"
        if incentives.p_star is not None and incentives.p_note:
            p += f" ({incentives.p_note})"
    return (path, _ending(automaton), *returns, p, _verdict(found, "ending_early_never_pays"),
            _verdict(found, "goal_earlier_never_pays_less"), _verdict(found, "stalling_never_pays"))


def rows(path: str, automaton: ir.Automaton) -> list[tuple[str, ...]]:
    """The file as it declares its episodes and, when it leaves the ending to the environment, as a
    gymnasium environment ending them at a collision or at the goal would run it."""
    found = [row(path, automaton)]
    ended = gym_ending(automaton)
    if ended is not None:
        found.append(row(path, ended))
    return found


def main(argv: Sequence[str] | None = None) -> int:
    """Print the table for the files in ``argv``; 0, or 1 when a file cannot be read or does not check."""
    parser = argparse.ArgumentParser(prog="python -m rac.studies.incentives", description=__doc__.split("\n")[0])
    parser.add_argument("files", nargs="+", help=".ra files")
    args = parser.parse_args(argv)
    table: list[tuple[str, ...]] = []
    status = 0
    for path in args.files:
        try:
            result = compile_file(path)
        except OSError as why:
            print(f"{path}: cannot be read: {why.strerror or why}", file=sys.stderr)
            status = 1
            continue
        if result.automaton is None or not result.ok:
            print(f"{path}: does not check (run `rac check {path}`)", file=sys.stderr)
            status = 1
            continue
        table.extend(rows(path, result.automaton))
    print("| " + " | ".join(COLUMNS) + " |")
    print("|" + "---|" * len(COLUMNS))
    for cells in table:
        print("| " + " | ".join(cell.replace("|", "\\|") for cell in cells) + " |")  # `||` in a cell
    return status


if __name__ == "__main__":
    raise SystemExit(main())
