"""Where rac's commands write: one folder per input file and command, ``FILE.out/COMMAND/`` beside
the file, or the folder the user names. The CLI (:mod:`rac.cli.common`) and the Python API of
``rac sweep`` (:mod:`rac.sweep`) both take it from here.
"""

from __future__ import annotations

from pathlib import Path

__all__ = ["OUTPUT_CONVENTION", "OUTPUT_SUFFIX", "output_folder"]

#: The suffix of the folder beside ``FILE.ra`` that receives every command's outputs (git-ignored as ``*.out/``).
OUTPUT_SUFFIX = ".out"
#: The convention in words, for ``rac --help`` and the docs.
OUTPUT_CONVENTION = (
    f"Outputs: each engine command writes into one folder per input file and command, FILE{OUTPUT_SUFFIX}/COMMAND/ "
    f"beside FILE.ra (e.g. driving{OUTPUT_SUFFIX}/verify/, driving{OUTPUT_SUFFIX}/simulate/), or into the folder "
    "given with -o/--out. A new run replaces the files of the previous run of the same command; no two "
    "commands, and no two results of one run, share a file name.")


def output_folder(source: Path, command: str, chosen: Path | None = None) -> Path:
    """The folder ``command``'s outputs for ``source`` go to: ``chosen`` (``-o``) when given, else
    ``FILE.out/COMMAND/`` beside the file (see :data:`OUTPUT_CONVENTION`)."""
    if chosen is not None:
        return chosen
    return source.with_name(source.stem + OUTPUT_SUFFIX) / command
