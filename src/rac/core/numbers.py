"""The integer limits every stage shares: the model computes with 32-bit integers (UPPAAL's
``int``, the emitted C's ``int32_t``, the engine's ``np.int32``)."""

from __future__ import annotations

__all__ = ["INT32_LOW", "INT32_MAX", "INT32_MIN"]

INT32_MAX = 2**31 - 1
INT32_MIN = -(2**31)
#: The most negative value rac writes or stores: ``-INT32_MAX``, because UPPAAL's lexer reads
#: ``-2147483648`` as the negation of a literal that does not fit.
INT32_LOW = -INT32_MAX
