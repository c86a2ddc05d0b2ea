"""The IR of ``stdlib/driving.ra``, built by hand (independent of the compiler).

Locations Normal/Uncomfortable/Stalled/Unsafe; rewards sa, pr, co; the ``*`` edges expanded per
source location in source order (``*`` excludes the edge's own target), guards nested the way
the resolver builds ``a && b && c`` (left-associated binary ``BAnd``).
"""

from __future__ import annotations

from fractions import Fraction

from rac import ir
from rac.core.source import Span

NORMAL, UNCOMFORTABLE, STALLED, UNSAFE = range(4)
LOCATIONS = ("Normal", "Uncomfortable", "Stalled", "Unsafe")
PENALTY = Fraction(100)


def _rates(*values: int) -> tuple[ir.Linear, ...]:
    return tuple(ir.Linear(Fraction(v)) for v in values)


def _add(reward: str, amount: Fraction) -> ir.Assignment:
    """``reward = reward + amount``."""
    return ir.Assignment(reward, ir.Linear(amount, ((reward, Fraction(1)),)))


def driving_automaton() -> ir.Automaton:
    """The checked automaton ``Driving`` of the language reference."""
    is_close, prog, comf, collide = (ir.BInput(n) for n in ("isClose", "prog", "comf", "collide"))
    not_close = ir.BNot(is_close)
    to_unsafe = (UNSAFE, is_close, (_add("sa", -PENALTY),))
    to_stalled = (STALLED, ir.BAnd((not_close, ir.BNot(prog))), ())
    to_uncomfortable = (UNCOMFORTABLE, ir.BAnd((ir.BAnd((not_close, prog)), ir.BNot(comf))), ())
    to_normal = (NORMAL, ir.BAnd((ir.BAnd((not_close, prog)), comf)), ())
    star = (to_unsafe, to_stalled, to_uncomfortable, to_normal)
    edges = []
    for source in range(4):
        group = [ir.Edge(source, target, guard, updates)
                 for target, guard, updates in star if target != source]
        if source == UNSAFE:
            group.append(ir.Edge(UNSAFE, UNSAFE, collide, (_add("sa", Fraction(-100)),)))
        edges.append(tuple(group))
    return ir.Automaton(
        name="Driving",
        inputs=(
            ir.Input("isClose", "bool"),
            ir.Input("prog", "bool"),
            ir.Input("comf", "bool"),
            ir.Input("collide", "bool"),
            ir.Input("dgoal", "real", Fraction(0), Fraction(500)),
        ),
        rewards=("sa", "pr", "co"),
        locations=(
            ir.Location("Normal", _rates(1, 1, 1)),
            ir.Location("Uncomfortable", _rates(1, 1, -1)),
            ir.Location("Stalled", _rates(1, -1, 0)),
            ir.Location("Unsafe", _rates(-1, 0, 0)),
        ),
        initial=NORMAL,
        edges=tuple(edges),
        end_clauses=(ir.EndClause(ir.BAtom("dgoal", "<", Fraction(2)), (_add("pr", Fraction(100)),)),),
        # as written on line 9 of stdlib/driving.ra (the runtimes quote it)
        assumptions=(ir.Assumption(ir.BOr((ir.BNot(collide), is_close)), "collide imply isClose",
                                   Span("driving.ra", 9, 5, 9, 33)),),
        objective=ir.Linear(Fraction(0), (("sa", Fraction(10)), ("pr", Fraction(5)), ("co", Fraction(1)))),
        priority=("sa", "pr", "co"),
        strict=False,
        period=Fraction(1, 10),
        horizon=Fraction(30),
        constants=(("PENALTY", PENALTY),),
        goal=ir.BAtom("dgoal", "<", Fraction(2)),
        collision=collide,
    )


def inputs(is_close: bool = False, prog: bool = True, comf: bool = True, collide: bool = False,
           dgoal: float = 50.0) -> dict[str, object]:
    """One input valuation (defaults: far from obstacles, progressing, comfortable)."""
    return {"isClose": is_close, "prog": prog, "comf": comf, "collide": collide, "dgoal": dgoal}


def compiled_driving() -> ir.Automaton:
    """``stdlib/driving.ra`` through the compiler."""
    from rac.compiler import compile_file
    from rac.lang.resources import stdlib_file

    result = compile_file(stdlib_file("driving.ra"))
    assert result.ok, result.diagnostics
    return result.automaton
