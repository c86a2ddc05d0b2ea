"""The driving reward automaton of ``stdlib/driving.ra``, written by hand: the benchmark's baseline.

This is what a Python programmer would write without rac, the idiomatic way (named constants,
a rate table, one validation helper shared by ``step`` and ``end``), with the same semantics and
the same input validation as :class:`rac.runtime.interpreter.RewardAutomaton`:

* every declared input must be present and nothing else (``ValueError`` naming the missing and
  unknown ones); booleans must be True/False or 0/1, ``dgoal`` a real number (read with
  ``float(v)``; a string, None or complex number is refused) and must lie in
  [0, 500] (which also refuses NaN and infinities); ``collide`` implies ``isClose`` (the
  ``assume``, named in the message as the generated module names it). A refused sample leaves the
  automaton untouched.
* one sample: every reward grows by its rate in the current location times the period, then the
  enabled edge (if any) is taken and its update applied; the reward handed out is the increase of
  ``10*sa + 5*pr + co``.
* ``end(inputs)`` adds the terminal bonus ``pr += 100`` when ``dgoal < 2`` and ends the run.

``benchmarks/run.py`` checks that this class returns bit-identical rewards to the runtime and the
generated module on its traces, and refuses the same invalid inputs, before it times anything.
"""

from __future__ import annotations

import numbers
from collections.abc import Mapping

NORMAL, UNCOMFORTABLE, STALLED, UNSAFE = "Normal", "Uncomfortable", "Stalled", "Unsafe"
INPUTS = ("isClose", "prog", "comf", "collide", "dgoal")
PERIOD = 0.1  # seconds per sample
PENALTY = 100.0  # sa lost when entering Unsafe, and per sample with a collision while Unsafe
GOAL_BONUS = 100.0  # pr gained at the end when the goal is nearer than 2 m
DGOAL_MIN, DGOAL_MAX = 0.0, 500.0

# Rates of (sa, pr, co) per second in each location, and their increase per sample.
RATES = {
    NORMAL: (1, 1, 1),
    UNCOMFORTABLE: (1, 1, -1),
    STALLED: (1, -1, 0),
    UNSAFE: (-1, 0, 0),
}
STEP_RATES = {location: tuple(rate * PERIOD for rate in rates) for location, rates in RATES.items()}



def _boolean(name: str, raw: object) -> bool:
    """A boolean input: True/False (Python's or numpy's) or 0/1; else ValueError."""
    if raw is True or raw is False:  # the common case, without the abstract-class check below
        return raw  # type: ignore[return-value]
    if type(raw).__name__ in ("bool", "bool_") or (isinstance(raw, numbers.Integral) and raw in (0, 1)):
        return bool(raw)
    raise ValueError(f"input {name!r} = {raw!r} is not a boolean (True or False)")


def _number(name: str, raw: object) -> float:
    """A numeric input: a real number, as a float; else ValueError."""
    if type(raw) is float:  # the common case, without the abstract-class check below
        return raw  # type: ignore[return-value]
    if not isinstance(raw, numbers.Real):
        raise ValueError(f"input {name!r} = {raw!r} is not a number")  # noqa: TRY004 - the documented error
    try:
        return float(raw)
    except OverflowError:
        raise ValueError(f"input {name!r} = {raw!r} is too large for a float") from None

class HandwrittenDriving:
    """Safety > progress > comfort, as a plain Python class."""

    def __init__(self) -> None:
        self.reset()

    def reset(self) -> None:
        self.location = NORMAL
        self.sa = self.pr = self.co = 0.0
        self.samples = 0
        self.ended = False
        self.objective = 0.0

    @staticmethod
    def _read(inputs: Mapping[str, object]) -> tuple[bool, bool, bool, bool, float]:
        """Validate one sample's inputs; raise ValueError without touching any state."""
        if type(inputs) is not dict and not isinstance(inputs, Mapping):
            raise ValueError(f"inputs must map input names to values, not {type(inputs).__name__}")  # noqa: TRY004
        try:
            if len(inputs) != len(INPUTS):
                raise KeyError
            is_close = _boolean("isClose", inputs["isClose"])
            prog = _boolean("prog", inputs["prog"])
            comf = _boolean("comf", inputs["comf"])
            collide = _boolean("collide", inputs["collide"])
            dgoal = _number("dgoal", inputs["dgoal"])
        except KeyError:
            missing = [name for name in INPUTS if name not in inputs]
            unknown = sorted(repr(key) for key in inputs if key not in INPUTS)
            parts = []
            if missing:
                parts.append("missing input(s): " + ", ".join(missing))
            if unknown:
                parts.append("unknown input(s): " + ", ".join(unknown))
            raise ValueError("; ".join(parts) or "the inputs do not match the declared inputs") from None
        if not DGOAL_MIN <= dgoal <= DGOAL_MAX:  # also false for NaN, which the message names (the module's words)
            message = f"input 'dgoal' = {dgoal!r} is outside [{DGOAL_MIN!r}, {DGOAL_MAX!r}]"
            if dgoal != dgoal:
                message += (": NaN (not a number) is in no range, and clip=True refuses it too; replace it before "
                            "the step (a sensor's missing value, a division by zero upstream)")
            raise ValueError(message)
        if collide and not is_close:  # the generated module's words: the clause, its line, what it reads
            raise ValueError(f"inputs violate `assume collide imply isClose` (driving.ra:9): collide={collide!r}, "
                             f"isClose={is_close!r}")
        return is_close, prog, comf, collide, dgoal

    def _increase(self) -> float:
        objective = 10.0 * self.sa + 5.0 * self.pr + self.co
        reward = objective - self.objective
        self.objective = objective
        return reward

    def step(self, inputs: Mapping[str, object]) -> float:
        """Take one sample; return the objective's increase."""
        if self.ended:
            raise RuntimeError("the run has ended; call reset() first")
        is_close, prog, comf, collide, _ = self._read(inputs)

        d_sa, d_pr, d_co = STEP_RATES[self.location]
        self.sa += d_sa
        self.pr += d_pr
        self.co += d_co

        if is_close:
            if self.location != UNSAFE:
                self.sa -= PENALTY
                self.location = UNSAFE
            elif collide:
                self.sa -= PENALTY
        elif not prog:
            self.location = STALLED
        elif not comf:
            self.location = UNCOMFORTABLE
        else:
            self.location = NORMAL

        self.samples += 1
        return self._increase()

    def end(self, inputs: Mapping[str, object]) -> float:
        """End the run with the final inputs; return the objective's increase."""
        if self.ended:
            raise RuntimeError("the run has ended; call reset() first")
        _, _, _, _, dgoal = self._read(inputs)
        if dgoal < 2.0:
            self.pr += GOAL_BONUS
        self.ended = True
        return self._increase()
