"""Where a warning about a training loop points: the first frame of the user's own code.

A warning of rac's learning environments and callbacks is issued deep inside other libraries' calls
(stable-baselines3's ``collect_rollouts``, gymnasium's wrappers around ``gymnasium.make``'s
environment), so a fixed ``stacklevel`` named a line of theirs, which no user can act on.
:func:`user_stacklevel` counts the frames to the first one outside :data:`LIBRARIES`: the training
script's ``learn()`` or its own loop's ``step()``.

May import: nothing of rac.
"""

from __future__ import annotations

import sys

__all__ = ["LIBRARIES", "user_stacklevel"]

#: The top-level packages between a training script and rac's warnings.
LIBRARIES = frozenset({"rac", "stable_baselines3", "sb3_contrib", "gymnasium", "torch", "highway_env"})


def user_stacklevel() -> int:
    """The ``stacklevel`` for ``warnings.warn`` called by this function's caller that names the first frame
    outside :data:`LIBRARIES` (the caller's own frame when every frame is inside them)."""
    frame = sys._getframe(1)
    level = 1
    while frame is not None:
        if str(frame.f_globals.get("__name__", "")).split(".")[0] not in LIBRARIES:
            return level
        frame, level = frame.f_back, level + 1  # type: ignore[assignment]
    return 1
