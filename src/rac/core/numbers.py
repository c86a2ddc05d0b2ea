"""The integer limits every stage shares: the model computes with 32-bit integers (UPPAAL's
``int``, the emitted C's ``int32_t``, the engine's ``np.int32``); and sizes in bytes as people read
them (:func:`format_bytes`: the engine's budgets and the scenario's load estimate say them alike)."""

from __future__ import annotations

import secrets
from decimal import Decimal
from fractions import Fraction
from typing import Any

from rac.core.diagnostics import short_number

__all__ = ["INT32_BOUND", "INT32_LOW", "INT32_MAX", "INT32_MIN", "MIN_SEED", "exact_decimal", "format_bytes",
           "fresh_seed", "samples_of", "seconds_at", "size_option"]

INT32_MAX = 2**31 - 1
#: The least seed rac takes (every command's --seed and --seeds, rac sweep's seed options): numpy's
#: SeedSequence, which every simulation and learner seeds from, takes any whole number from 0 up.
MIN_SEED = 0
INT32_MIN = -(2**31)
#: ``2**31``: no int32 is larger in magnitude. A double ``d`` truncates into an int32 significand when
#: ``-INT32_BOUND < d < INT32_BOUND`` (the model's range checks; NaN never does); it also bounds exact sums.
INT32_BOUND = 2**31
#: The most negative value rac writes or stores: ``-INT32_MAX``, because UPPAAL's lexer reads
#: ``-2147483648`` as the negation of a literal that does not fit.
INT32_LOW = -INT32_MAX


def fresh_seed() -> int:
    """A seed drawn now, for a command given none: 32 bits, short enough to print and give back as ``--seed N``
    (numpy's ``SeedSequence().generate_state(1)[0]``, which rac verify drew before this owner)."""
    return secrets.randbits(32)


def exact_text(value: Fraction) -> str:
    """``value`` as `.ra` reads it back exactly: an integer, or ``a / b`` (``197 / 2``)."""
    if value.denominator == 1:
        return str(value.numerator)
    return f"{value.numerator} / {value.denominator}"


def exact_decimal(value: Fraction, max_places: int | None = None) -> str | None:
    """``value`` as a decimal with exactly its value and no exponent (``0.05``, ``-12.5``, ``3``), or
    None when it has none (``1/3``) or needs more than ``max_places`` digits after the point."""
    if value.denominator == 1:
        return str(value.numerator)
    rest, places = value.denominator, 0
    for prime in (2, 5):
        count = 0
        while rest % prime == 0:
            rest, count = rest // prime, count + 1
        places = max(places, count)
    if rest != 1 or (max_places is not None and places > max_places):
        return None
    digits = str(abs(value.numerator) * 10**places // value.denominator).rjust(places + 1, "0")
    return ("-" if value < 0 else "") + f"{digits[:-places]}.{digits[-places:]}"


def format_bytes(size: float) -> str:
    """``size`` for people: ``2 MB``, ``1.5 GB``; an integer too large for a float too (an estimate
    for a horizon of ``1e400`` s is one: ``1.2e+380 TB``)."""
    for unit, scale in (("TB", 2**40), ("GB", 2**30), ("MB", 2**20), ("kB", 2**10)):
        if size >= scale:
            return f"{_ratio(size, scale):.3g} {unit}"
    return f"{int(size)} B"


def size_option(size: int) -> str:
    """``size`` rounded up to what ``--max-memory`` reads: ``1.6G``, ``300M`` (a budget that holds it)."""
    if size >= 2**30:
        if size > 2**100:  # beyond any machine: its magnitude, not a budget to type
            return f"{_ratio(size, 2**30):.3g}G"
        tenths = -(-size * 10 // 2**30)  # rounded up in integers: a float loses the last byte of large sizes
        return f"{tenths // 10}G" if tenths % 10 == 0 else f"{tenths // 10}.{tenths % 10}G"
    return f"{-(-size // 2**20)}M"


def _ratio(size: float, scale: int) -> float | Decimal:
    """``size / scale``, exact as a :class:`~decimal.Decimal` where the float would overflow."""
    try:
        return size / scale
    except OverflowError:  # an int beyond float's range: Decimal keeps its magnitude
        return Decimal(size) / scale


def samples_of(seconds: Fraction, period: Fraction, *, what: str = "--horizon", period_name: str = "") -> int:
    """``seconds`` as a whole number of samples of ``period`` s; ``ValueError`` naming it as ``what`` (and
    the period as ``period_name``, e.g. ``"C1 = "``) when it is not one, or is more than
    :data:`INT32_MAX` samples (the model counts samples in int32; numpy refuses arrays that long anyway)."""
    samples = seconds / period
    of = f"{period_name}{short_number(period)} s"
    if samples.denominator != 1:
        raise ValueError(f"{what} {short_number(seconds)} is not a whole number of samples of {of}")
    if samples > INT32_MAX:
        raise ValueError(f"{what} {short_number(seconds)} is {short_number(samples)} samples of {of}: more than "
                         f"{INT32_MAX:,}")
    return int(samples)


def seconds_at(samples: Any, period: Fraction) -> Any:
    """The time in seconds of sample ``samples`` (an int, or an integer numpy array) at ``period`` s,
    rounded once: ``samples * numerator / denominator``, so multiples of 0.1 s read as written
    (``7.1``, where ``71 * 0.1`` gives ``7.1000000000000005``)."""
    return samples * period.numerator / period.denominator
