"""rac.targets.uppaal.names: names are valid UPPAAL identifiers, never keywords, never colliding."""

from __future__ import annotations

import itertools
import re

from rac.targets.uppaal.names import RESERVED, Names, mirror_name

IDENTIFIER = re.compile(r"[A-Za-z_][A-Za-z0-9_]*")


def test_plain_names_are_kept() -> None:
    names = Names(["isClose", "sa", "Normal"])
    assert [names[n] for n in ("isClose", "sa", "Normal")] == ["isClose", "sa", "Normal"]


def test_reserved_words_get_a_trailing_underscore() -> None:
    assert {"int", "clock", "A", "E", "sum", "deadlock", "location"} <= RESERVED
    names = Names(["int", "clock", "E"])
    assert (names["int"], names["clock"], names["E"]) == ("int_", "clock_", "E_")


def test_a_rename_never_takes_another_user_name() -> None:
    names = Names(["int", "int_"])  # `int` would become `int_`, which the user already has
    assert names["int_"] == "int_"
    assert names["int"] == "int__"


def test_fresh_names_avoid_user_names_reserved_words_and_each_other() -> None:
    names = Names(["count", "Timer"], reserved=["extra"])
    assert names.fresh("count") == "count_"
    assert names.fresh("count") == "count__"
    assert names.fresh("Timer") == "Timer_"
    assert names.fresh("extra") == "extra_"
    assert names.fresh("int") == "int_"
    assert names.fresh("fresh") == "fresh"


def test_brute_force_small_vocabularies_are_injective_and_valid() -> None:
    """Every set of up to three names from a pool with keywords and their underscored forms."""
    pool = ["int", "int_", "E", "E_", "x", "clock", "sa"]
    for size in range(4):
        for chosen in itertools.combinations(pool, size):
            names = Names(chosen)
            mapped = [names[n] for n in chosen]
            added = [names.fresh(base) for base in ("x", "int", "count", "count")]
            everything = mapped + added
            assert len(set(everything)) == len(everything), chosen
            for name in everything:
                assert IDENTIFIER.fullmatch(name) and name not in RESERVED, (chosen, name)
            assert not set(added) & set(chosen), chosen
            # a name UPPAAL does not reserve, and whose underscored forms do not stand for a keyword, is kept
            assert all(m == n for n, m in zip(chosen, mapped, strict=True) if n.rstrip("_") not in RESERVED), chosen


def test_mirror_name() -> None:
    assert mirror_name("sa") == "iSa"
    assert mirror_name("comfort") == "iComfort"
