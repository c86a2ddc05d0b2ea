"""Where a warning about a training loop points: the first frame of the user's own code.

A warning of rac's learning environments and callbacks is issued deep inside other libraries' calls
(stable-baselines3's ``collect_rollouts``, gymnasium's wrappers around ``gymnasium.make``'s
environment), so a fixed ``stacklevel`` named a line of theirs, which no user can act on.
:func:`user_stacklevel` counts the frames to the first one outside :data:`LIBRARIES`: the training
script's ``learn()`` or its own loop's ``step()``. In a worker process (stable-baselines3's ``SubprocVecEnv``,
gymnasium's ``AsyncVectorEnv``) the frames above the library's worker loop are :data:`LAUNCHERS`'s, which no user
can act on either: past them a forked worker still holds the parent's frames at the fork, the script's line that
made the vector environment; a spawned one only its bootstrap (``<string>``), and the warning names rac's own line.

:func:`callers` walks the frames above a function that reads who is calling it (a ``TimeLimit``'s or a reward
wrapper's ``reset`` outside an environment, the vector environment stepping it).

:func:`require_bool` checks a switch the user's code passes (``clip=``, ``counterfactuals=``): Python takes any
non-empty text as true, so ``clip="no"`` clipped.

May import: nothing of rac.
"""

from __future__ import annotations

import sys
from collections.abc import Iterator
from types import FrameType

__all__ = ["LAUNCHERS", "LIBRARIES", "callers", "require_bool", "user_stacklevel"]

#: The top-level packages between a training script and rac's warnings.
LIBRARIES = frozenset({"rac", "stable_baselines3", "sb3_contrib", "gymnasium", "torch", "highway_env"})

#: The standard library's packages that start a worker process and call the library's worker loop in it.
LAUNCHERS = frozenset({"multiprocessing", "concurrent"})


def user_stacklevel() -> int:
    """The ``stacklevel`` for ``warnings.warn`` called by this function's caller that names the first frame
    outside :data:`LIBRARIES` and :data:`LAUNCHERS` (the caller's own frame when there is none, or when past a
    launcher it is a spawned process's bootstrap, code without a file)."""
    frame = sys._getframe(1)
    level = 1
    launched = False
    while frame is not None:
        package = str(frame.f_globals.get("__name__", "")).split(".")[0]
        if package in LAUNCHERS:
            launched = True
        elif package not in LIBRARIES:
            # multiprocessing's spawn and forkserver start the worker from `python -c ...`: no line of the user's
            return 1 if launched and frame.f_code.co_filename.startswith("<") else level
        frame, level = frame.f_back, level + 1  # type: ignore[assignment]
    return 1


def callers(frames: int) -> Iterator[FrameType]:
    """The ``frames`` innermost frames above the function that iterates this, its caller first (fewer at the
    stack's top)."""
    frame = sys._getframe(1).f_back  # sys._getframe(1): the iterating function's (this generator's is 0)
    for _ in range(frames):
        if frame is None:
            return
        yield frame
        frame = frame.f_back


def require_bool(value: object, name: str) -> bool:
    """``value`` as a bool when it is one (NumPy's ``np.bool_`` too), else a ``TypeError`` naming the argument
    ``name``: a text or number there (``clip="yes"``, ``clip="no"``, ``clip=0.5``) was taken by its truth."""
    # np.bool_ (named "bool" in NumPy 2) without importing NumPy here
    if isinstance(value, bool) or (type(value).__module__ == "numpy" and type(value).__name__ in ("bool", "bool_")):
        return bool(value)
    raise TypeError(f"{name} must be True or False, not {value!r}")
