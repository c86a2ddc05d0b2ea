"""rac — the reward-automata compiler.

Write a multi-objective reward as a reward automaton (``.ra``), have rac prove
that its priority order holds, and train with it::

    import rac
    ra = rac.load("stdlib/driving.ra")   # raises rac.CheckError on errors
    ra.reset()
    r = ra.step({"isClose": False, "prog": True, "comf": True, "collide": False, "dgoal": 40.0})
"""

from __future__ import annotations

import importlib
from pathlib import Path
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from rac.compiler import CompileResult, compile_file, compile_text
    from rac.core.diagnostics import CheckError, Diagnostic, RacError
    from rac.runtime.interpreter import RewardAutomaton  # the same: loaded on first use

__version__ = "0.1.0"
__all__ = ["CheckError", "CompileResult", "Diagnostic", "RacError", "RewardAutomaton", "compile_file", "compile_text",
           "load", "loads"]


def load(path: str | Path) -> RewardAutomaton:
    """Check a `.ra` file and return its automaton, ready to ``reset``/``step``/``end``.

    Raises :class:`CheckError` (with every diagnostic) if the file has errors; its warnings (W
    codes: an unreachable location, a loophole the reward leaves open, ...) become one
    :class:`~rac.core.diagnostics.RacCheckWarning`.
    """
    # the compiler loads on first use: `import rac` (rac --version) stays light
    from rac.compiler import compile_file
    from rac.runtime.interpreter import RewardAutomaton  # the same: loaded on first use

    return RewardAutomaton(compile_file(path).raise_for_errors(warn=True))


def loads(text: str, name: str = "<string>") -> RewardAutomaton:
    """Like :func:`load`, for source text."""
    # the compiler loads on first use: `import rac` (rac --version) stays light
    from rac.compiler import compile_text
    from rac.runtime.interpreter import RewardAutomaton  # the same: loaded on first use

    return RewardAutomaton(compile_text(text, name).raise_for_errors(warn=True))


#: The public names defined elsewhere, imported on first use (PEP 562): ``import rac`` and ``rac
#: --version`` then load neither the checker nor numpy.
_LAZY = {"CheckError": "rac.core.diagnostics", "Diagnostic": "rac.core.diagnostics", "RacError": "rac.core.diagnostics",
         "CompileResult": "rac.compiler", "compile_file": "rac.compiler", "compile_text": "rac.compiler",
         "RewardAutomaton": "rac.runtime.interpreter"}  # what load() returns: annotations and isinstance name it


def __getattr__(name: str) -> Any:
    module = _LAZY.get(name)
    if module is None:
        raise AttributeError(f"module 'rac' has no attribute {name!r}")
    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value


def __dir__() -> list[str]:
    return sorted({*globals(), *_LAZY})
