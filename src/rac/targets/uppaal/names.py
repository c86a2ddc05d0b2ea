"""UPPAAL identifiers: the words UPPAAL reserves, and the names of one emitted model.

A ``.ra`` name is kept unless UPPAAL reserves it (then it gets a trailing ``_``); every name the
target adds (``count``, ``Timer``, ``iSa``, ...) is fresh: never equal to a ``.ra`` name.
"""

from __future__ import annotations

from collections.abc import Iterable

__all__ = ["RESERVED", "Names", "mirror_name"]

#: Words UPPAAL's lexer or parser reserves (utap keywords.cpp, lexer.l, parser.y's NonTypeId and
#: built-in declarations): a ``.ra`` name equal to one of them is renamed with a trailing ``_``.
RESERVED = frozenset("""
    const select guard sync assign probability process state branchpoint init trans urgent commit
    broadcast system true false and or xor not imply for while do if else default return typedef
    struct import meta before_update after_update progress gantt assert IO forall exists sum deadlock
    priority bool int double string chan clock void scalar control control_t simulation minE
    loadStrategy saveStrategy maxE minPr maxPr under imitate strategy simulate sat inf sup bounds Pmax
    Pr X abs fabs fmod fma fmax fmin fdim exp exp2 expm1 ln log log10 log2 log1p pow sqrt cbrt hypot
    sin cos tan asin acos atan atan2 sinh cosh tanh asinh acosh atanh erf erfc tgamma lgamma ceil
    floor trunc round fint ldexp ilogb logb nextafter nexttoward copysign fpclassify isfinite isinf
    isnan isnormal signbit isunordered random random_arcsine random_beta random_gamma random_normal
    random_poisson random_tri random_weibull hybrid dynamic spawn exit numOf foreach query location
    break continue switch case chan_priority quit
    A E U W R M
    INT8_MIN INT8_MAX UINT8_MAX INT16_MIN INT16_MAX UINT16_MAX INT32_MIN INT32_MAX int8_t uint8_t
    int16_t uint16_t int32_t FLT_MIN FLT_MAX DBL_MIN DBL_MAX M_PI M_PI_2 M_PI_4 M_E M_LOG2E M_LOG10E
    M_LN2 M_LN10 M_1_PI M_2_PI M_2_SQRTPI M_SQRT2 M_SQRT1_2
""".split())


class Names:
    """UPPAAL identifiers: the ``.ra`` names (renamed only when UPPAAL reserves them) and fresh
    names for everything the target adds, never equal to a ``.ra`` name."""

    def __init__(self, user: Iterable[str], reserved: Iterable[str] = ()):
        self.raw = set(user)
        self.reserved = RESERVED | frozenset(reserved)
        self.taken: set[str] = set()
        self.user: dict[str, str] = {}
        for name in sorted(self.raw):
            candidate = name
            while (candidate in self.reserved or (candidate != name and candidate in self.raw)
                   or candidate in self.taken):
                candidate += "_"
            self.user[name] = candidate
            self.taken.add(candidate)

    def fresh(self, base: str) -> str:
        candidate = base
        while candidate in self.reserved or candidate in self.raw or candidate in self.taken:
            candidate += "_"
        self.taken.add(candidate)
        return candidate

    def __getitem__(self, name: str) -> str:
        return self.user[name]


def mirror_name(reward: str) -> str:
    return "i" + reward[:1].upper() + reward[1:]
