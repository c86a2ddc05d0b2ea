"""What a reward automaton pays for over its horizon (issue 25): the risk tolerance p* and three loopholes.

Knox et al., "Reward (Mis)design for Autonomous Driving", judge a reward by the returns of whole
runs: ``R_goal`` (the best safe run that reaches the goal), ``R_stall`` (the best safe run that never
does) and ``R_crash`` (the best run that collides). A learner that maximises the return accepts a
crash probability up to ``p* = (R_goal - R_stall) / (R_goal - R_crash)`` to reach the goal rather
than stall. With ``episode ends when``, a run may end early; three loopholes are checked:

- ending early never pays: at no point does ending there (without the goal) earn more than the best
  safe continuation from the same point;
- reaching the goal earlier never pays less: ``G(k)``, the best return of a safe run first reaching
  the goal at sample ``k``, never grows with ``k``;
- stalling never beats reaching the goal: ``R_stall <= G(k)`` for every ``k``.

Runs (docs/checks.md): inputs are free at each sample (subject to ``assume``); a run ends at the
first sample whose inputs satisfy ``episode ends when``, else at the horizon, where its ``at end``
clauses read the last sample's inputs (the gym wrappers pass them to ``end()``).

Method: when every update is a translation (``r = r + c``, ``c`` linear in numeric inputs) the return
is additive along a run. A sample's *gain* is what it adds to the objective: the edge's updates, then
either the accrual in the new location (which reads the same, held, inputs) or, when the run ends
there, the ``at end`` clauses; the first sample also accrues in the initial location with its own
inputs. A gain is one linear form over one box of the inputs, its supremum exact
(:func:`~rac.check.analysis.affine.sup_linear`). Every quantity is then a max-plus dynamic programme
over (sample, location) and at most one flag, over the outcomes of
:func:`~rac.check.analysis.affine.outcomes` split by the truth of ``episode ends``, ``goal``,
``collision`` and the ``at end`` guards: finite, exact rationals, and a witness run for each value.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from fractions import Fraction

from rac import ir
from rac.check.analysis.affine import (
    Affine,
    EndOutcome,
    Moves,
    Outcome,
    accrual,
    from_assignments,
    identity,
    moves,
    sup_weighted,
    then,
)
from rac.check.analysis.priority import describe_run, end_json, replay, replayable_runs_json, run_json
from rac.check.analysis.worst import AFTER_EDGE, AFTER_END, CONTINUE, MAX_SAMPLES, Step, Worst
from rac.core.diagnostics import INCENTIVES_UNDONE, Diagnostic, Fact, Note, error, short_number, warning
from rac.core.numbers import exact_decimal
from rac.core.source import Span
from rac.ir.inputs import InputSpace, guard_inputs

__all__ = ["CODES", "Findings", "Incentives", "Loophole", "Move", "Run", "Runs", "Unchecked", "analyse",
           "check_incentives", "risk_tolerance", "split_guards", "unchecked"]

ZERO = Fraction(0)
FALSE = ir.BConst(False)
_Point = dict[str, Fraction]


@dataclass(frozen=True)
class Move:
    """One outcome of a sample with what the checks read of it: the flags and the gains."""

    outcome: Outcome
    ends: bool  # `episode ends when` holds: the run ends at this sample
    goal: bool
    collision: bool
    clauses: tuple[int, ...]  # the `at end` clauses that apply if the run ends here
    end_map: Affine
    #: (value, inputs) of the gain when the run goes on / stops here, at the first sample and later.
    going: tuple[tuple[Fraction, _Point], tuple[Fraction, _Point]]
    stopping: tuple[tuple[Fraction, _Point], tuple[Fraction, _Point]]


@dataclass(frozen=True)
class Run:
    """A witness run: its return, the samples it takes (as :mod:`~rac.check.analysis.worst` runs are
    described and replayed: ``worst``), why it ends, and its first goal sample (None: none)."""

    value: Fraction
    worst: Worst
    ended_by: str  # "episode" (`episode ends when` held) or "horizon"
    goal_sample: int | None

    @property
    def samples(self) -> int:
        return len(self.worst.steps)


@dataclass(frozen=True)
class Loophole:
    """A counterexample to one of the three checks: the better run, the run it beats, the gap ``delta``
    (objective units), the sample(s) concerned, and for ending early the common prefix's length."""

    check: str
    better: Run
    worse: Run
    delta: Fraction
    sample: int
    other_sample: int | None = None
    prefix: int = 0


@dataclass(frozen=True)
class Unchecked:
    """The checks could not be made exactly; ``reason`` says why (a warning, never a verdict)."""

    reason: str


@dataclass(frozen=True)
class Incentives:
    """The returns (None: no such run) with their witnesses, and p* (None: undefined; ``p_note`` says why)."""

    goal: Run | None
    stall: Run | None
    crash: Run | None
    p_star: Fraction | None
    p_note: str
    #: G(k) per sample k (1-based) at which a safe run can first reach the goal.
    goal_by_sample: dict[int, Fraction]


@dataclass(frozen=True)
class Findings:
    """What :func:`analyse` found: the incentives (with ``goal when``), and per check its verdict:
    None (proved), a :class:`Loophole`; a check whose declarations are missing is left out."""

    incentives: Incentives | None
    verdicts: dict[str, Loophole | None]


def split_guards(automaton: ir.Automaton) -> tuple[ir.Guard, ...]:
    """The guards the checks tell a sample's outcomes apart by: `episode ends`, `goal`, `collision`
    (``false`` when not declared), then each ``at end`` clause's."""
    return (automaton.episode_ends or FALSE, automaton.goal or FALSE, automaton.collision or FALSE,
            *(c.guard for c in automaton.end_clauses))


def unchecked(automaton: ir.Automaton, outs: Moves) -> Unchecked | None:
    """Why the checks cannot be exact here, or None."""
    scaling = not outs.translations_only or any(
        not from_assignments(c.updates, automaton.rewards).is_translation for c in automaton.end_clauses)
    if scaling:
        return Unchecked("an update scales or resets a reward (not `r = r + c`), so a run's return is not "
                         "the sum of its samples' gains")
    if automaton.steps > MAX_SAMPLES:
        return Unchecked(f"the horizon has {automaton.steps:,} samples, more than the {MAX_SAMPLES:,} the "
                         "checks go through")
    return None


def _useful(found: list[Move]) -> list[Move]:
    """The moves a best run may take: per (target, flags), the best to go on and the best to stop with, at
    the first sample and later (the others never do better; dropping them keeps every value exact)."""
    best: dict[tuple, Move] = {}
    for m in found:
        group = (m.outcome.target, m.ends, m.goal, m.collision)
        for which, gains in (("going", m.going), ("stopping", m.stopping)):
            for first in (0, 1):
                key = (*group, which, first)
                if key not in best or gains[first][0] > getattr(best[key], which)[first][0]:
                    best[key] = m
    kept = {id(m) for m in best.values()}
    return [m for m in found if id(m) in kept]


class Runs:
    """The runs of one automaton as moves with gains, and the dynamic programmes over them.

    ``prune``: keep only the moves a best run may take (:func:`_useful`); without it, ``moves[l]`` holds
    every outcome of location ``l`` in the order of ``outs``, so that the runs of the same automaton at
    other values of a parameter line up move for move (:mod:`~rac.check.analysis.parametric`).
    """

    def __init__(self, automaton: ir.Automaton, space: InputSpace, outs: Moves, prune: bool = True) -> None:
        self.automaton, self.space = automaton, space
        self.steps = automaton.steps
        self.l0 = automaton.initial
        self.c0 = automaton.objective.const
        w = tuple(automaton.objective.coefficient(r) for r in automaton.rewards)
        accruals = [accrual(loc, automaton.period) for loc in automaton.locations]
        clause_maps = [from_assignments(c.updates, automaton.rewards) for c in automaton.end_clauses]
        self.moves: list[list[Move]] = []
        for os in outs.samples:
            found = []
            for o in os:
                ends, goal, collision, *enabled = o.flags
                clauses = tuple(i for i, on in enumerate(enabled) if on)
                end_map = identity(len(automaton.rewards))
                for i in clauses:
                    end_map = then(end_map, clause_maps[i])
                first = (accruals[self.l0],)
                going = (o.edge_map, accruals[o.target])
                stopping = (o.edge_map, end_map)
                found.append(Move(
                    o, bool(ends), bool(goal), bool(collision), clauses, end_map,
                    (sup_weighted(w, first + going, o.box), sup_weighted(w, going, o.box)),
                    (sup_weighted(w, first + stopping, o.box), sup_weighted(w, stopping, o.box))))
            if not prune:
                self.moves.append(found)
                continue
            # Staying first: among runs that earn alike, the witnesses stay rather than move for nothing.
            found.sort(key=lambda m: m.outcome.edge is not None)
            self.moves.append(_useful(found))
        # The programmes add and compare scaled integers (exact, and far faster than fractions).
        values = [self.c0] + [g[0] for ms in self.moves for m in ms for g in (*m.going, *m.stopping)]
        self.scale = math.lcm(*(v.denominator for v in values))
        self.start = int(self.c0 * self.scale)
        self.gains = {id(m): tuple(int(g[0] * self.scale) for g in (*m.going, *m.stopping))
                      for ms in self.moves for m in ms}
        # The programmes' inner loops read each move's fields from one flat tuple (they run over every
        # sample: at 90,000 samples, attribute and dictionary lookups were most of `rac check`'s time).
        self.entries: list[list[tuple[int, Move, int, bool, bool, bool, int, int, int, int]]] = []
        for ms in self.moves:
            entries = []
            for i, m in enumerate(ms):
                g_first, g_later, s_first, s_later = self.gains[id(m)]
                entries.append((i, m, m.outcome.target, m.ends, m.goal, m.collision, g_first, g_later, s_first,
                                s_later))
            self.entries.append(entries)

    def stops(self, m: Move, k: int) -> bool:
        return m.ends or k == self.steps

    def gain(self, m: Move, k: int, stop: bool) -> int:
        """The move's gain at sample ``k``, scaled (``Fraction(gain, self.scale)`` is its value)."""
        return self.gains[id(m)][(2 if stop else 0) + (0 if k == 1 else 1)]

    def value(self, scaled: int) -> Fraction:
        return Fraction(scaled, self.scale)

    # ---------------------------------------------------------------- forward: prefixes
    def forward(self, step: Callable[[int, Move], int | None], start: int = 0) -> list[dict]:
        """layers[k][(location, state)] = (best value after k samples of a run not ended yet, back
        pointer (previous key, move index)), for k = 0 .. steps-1; ``step`` gives a move's next state,
        None where the run may not take it."""
        layers: list[dict] = [{(self.l0, start): (self.start, None)}]
        entries = self.entries
        for k in range(1, self.steps):
            layer: dict = {}
            get = layer.get
            first = k == 1
            for key, (value, _) in layers[-1].items():
                here, state = key
                for i, m, target, ends, _, _, going_first, going, _, _ in entries[here]:
                    if ends:
                        continue
                    following = step(state, m)
                    if following is None:
                        continue
                    total = value + (going_first if first else going)
                    reached = (target, following)
                    old = get(reached)
                    if old is None or total > old[0]:
                        layer[reached] = (total, (key, i))
            layers.append(layer)
        return layers

    def prefix(self, layers: list[dict], k: int, key: tuple[int, int]) -> list[tuple[int, Move]]:
        """The moves of the best prefix of ``k`` samples reaching ``key``."""
        found: list[tuple[int, Move]] = []
        while k > 0:
            _, (previous, i) = layers[k][key]
            found.append((k, self.moves[previous[0]][i]))
            key, k = previous, k - 1
        return found[::-1]

    # ---------------------------------------------------------------- backward: safe rests
    def safe_rests(self) -> list[dict[int, tuple[int, int]]]:
        """rests[k][l] = (the best the rest of a safe run earns after k samples in l, the first move's
        index), for k = 0 .. steps-1; a location without a safe rest is missing."""
        rests: list[dict[int, tuple[int, int]]] = [{} for _ in range(self.steps + 1)]
        for k in range(self.steps - 1, -1, -1):
            after = rests[k + 1]
            first, last = k + 1 == 1, k + 1 == self.steps
            for here, entries in enumerate(self.entries):
                best: tuple[int, int] | None = None
                for i, _, target, ends, _, collision, going_first, going, stop_first, stop in entries:
                    if collision:
                        continue
                    if ends or last:  # self.rest(m, k + 1, rests), inlined
                        value = stop_first if first else stop
                    else:
                        then = after.get(target)
                        if then is None:
                            continue
                        value = (going_first if first else going) + then[0]
                    if best is None or value > best[0]:
                        best = (value, i)
                if best is not None:
                    rests[k][here] = best
        return rests

    def rest(self, m: Move, k: int, rests: list[dict[int, tuple[int, int]]]) -> int | None:
        """What a run taking ``m`` at sample ``k`` earns from there on, its rest safe (None: none)."""
        if self.stops(m, k):
            return self.gain(m, k, True)
        after = rests[k].get(m.outcome.target)
        return None if after is None else self.gain(m, k, False) + after[0]

    def suffix(self, m: Move, k: int, rests: list[dict[int, tuple[int, int]]]) -> list[tuple[int, Move]]:
        """``m`` at sample ``k``, then the best safe rest's moves."""
        found = [(k, m)]
        while not self.stops(m, k):
            here = m.outcome.target
            m = self.moves[here][rests[k][here][1]]
            k += 1
            found.append((k, m))
        return found

    # ---------------------------------------------------------------- runs
    def run(self, taken: list[tuple[int, Move]]) -> Run:
        """A run of the given moves (sample, move), its value summed again from the gains."""
        value = self.c0
        steps: list[Step] = []
        goal_sample = None
        for k, m in taken:
            stop = self.stops(m, k)
            gain, point = (m.stopping if stop else m.going)[0 if k == 1 else 1]
            value += gain
            steps.append(Step(k, m.outcome, point, AFTER_EDGE if stop else CONTINUE))
            if m.goal and goal_sample is None:
                goal_sample = k
        k, last = taken[-1]
        point = steps[-1].inputs
        worst = Worst(value, steps, AFTER_END, EndOutcome(last.outcome.cls, last.clauses, last.outcome.box,
                                                          last.end_map), point)
        return Run(value, worst, "episode" if last.ends else "horizon", goal_sample)


def _incentives(runs: Runs, rests: list[dict[int, tuple[int, int]]], quiet: list[dict]) -> Incentives:
    """R_goal, R_stall, R_crash with their witnesses, G(k) and p*."""
    # quiet: prefixes that neither collide nor reach the goal.
    goal_by_sample: dict[int, int] = {}
    best_goal: tuple[int, int, tuple, Move] | None = None
    best_stall: tuple[int, int, tuple, Move] | None = None
    for k in range(1, runs.steps + 1):
        first, last = k == 1, k == runs.steps
        for key, (value, _) in quiet[k - 1].items():
            for _, m, _, ends, goal, collision, _, _, stop_first, stop in runs.entries[key[0]]:
                if collision:
                    continue
                if goal:  # few moves reach the goal: the shared rule, not an inlined copy
                    rest = runs.rest(m, k, rests)
                    if rest is None:
                        continue
                    total = value + rest
                    if k not in goal_by_sample or total > goal_by_sample[k]:
                        goal_by_sample[k] = total
                    if best_goal is None or total > best_goal[0]:
                        best_goal = (total, k, key, m)
                elif ends or last:
                    total = value + (stop_first if first else stop)
                    if best_stall is None or total > best_stall[0]:
                        best_stall = (total, k, key, m)
    goal = stall = None
    if best_goal is not None:
        _, k, key, m = best_goal
        goal = runs.run(runs.prefix(quiet, k - 1, key) + runs.suffix(m, k, rests))
    if best_stall is not None:
        _, k, key, m = best_stall
        stall = runs.run(runs.prefix(quiet, k - 1, key) + [(k, m)])
    crash = None
    if runs.automaton.collision is not None:
        crashed = runs.forward(lambda state, m: 1 if state or m.collision else 0)
        best_crash: tuple[int, int, tuple, Move] | None = None
        for k in range(1, runs.steps + 1):
            first, last = k == 1, k == runs.steps
            for key, (value, _) in crashed[k - 1].items():
                for _, m, _, ends, _, collision, _, _, stop_first, stop in runs.entries[key[0]]:
                    if (ends or last) and (key[1] or collision):
                        total = value + (stop_first if first else stop)
                        if best_crash is None or total > best_crash[0]:
                            best_crash = (total, k, key, m)
        if best_crash is not None:
            _, k, key, m = best_crash
            crash = runs.run(runs.prefix(crashed, k - 1, key) + [(k, m)])
    p_star, note = risk_tolerance(goal, stall, crash, runs.automaton.collision is not None)
    return Incentives(goal, stall, crash, p_star, note, {k: runs.value(v) for k, v in goal_by_sample.items()})


def risk_tolerance(goal: Run | None, stall: Run | None, crash: Run | None,
                   collision: bool = True) -> tuple[Fraction | None, str]:
    """p* and a phrase for its edge cases ("" when it is a plain probability in (0, 1))."""
    if goal is None:
        return None, "no safe run reaches the goal"
    if not collision:
        return None, "no `collision when` declared: no risk to weigh"
    if crash is None:
        return None, "no run collides: no risk to weigh"
    if stall is None:
        return None, "every safe run reaches the goal: no stalling to weigh the risk against"
    if crash.value >= goal.value:
        return None, ("a crash pays at least as much as reaching the goal (R_crash >= R_goal): any crash risk "
                      "is accepted")
    p = (goal.value - stall.value) / (goal.value - crash.value)
    if p <= 0:
        return p, "stalling pays at least as much as reaching the goal (R_stall >= R_goal): no risk is worth taking"
    if p >= 1:
        return p, "p* >= 1: any crash risk is accepted"
    return p, ""


def _ending_early(runs: Runs, rests: list[dict[int, tuple[int, int]]], anyway: list[dict]) -> Loophole | None:
    """The point where ending early (without the goal) beats the best safe continuation the most."""
    found: tuple[int, int, tuple, Move, Move] | None = None
    for k in range(1, runs.steps + 1):
        for key in anyway[k - 1]:
            ms = runs.moves[key[0]]
            early = [(runs.gain(m, k, True), m) for m in ms if m.ends and not m.goal]
            if not early:
                continue
            e_value, e_move = max(early, key=lambda item: item[0])
            safe: tuple[int, Move] | None = None
            for m in ms:
                if m.collision or (m.ends and not m.goal):
                    continue
                value = runs.rest(m, k, rests)
                if value is not None and (safe is None or value > safe[0]):
                    safe = (value, m)
            if safe is None or e_value <= safe[0]:
                continue
            delta = e_value - safe[0]
            if found is None or delta > found[0]:
                found = (delta, k, key, e_move, safe[1])
    if found is None:
        return None
    delta, k, key, e_move, s_move = found
    prefix = runs.prefix(anyway, k - 1, key)
    return Loophole("ending_early_never_pays", runs.run(prefix + [(k, e_move)]),
                    runs.run(prefix + runs.suffix(s_move, k, rests)), runs.value(delta), k, prefix=k - 1)


def _goal_run(runs: Runs, rests: list[dict[int, tuple[int, int]]], quiet: list[dict], k: int) -> Run:
    """The best safe run first reaching the goal at sample ``k`` (one exists)."""
    best: tuple[int, tuple, Move] | None = None
    for key, (value, _) in quiet[k - 1].items():
        for m in runs.moves[key[0]]:
            if m.goal and not m.collision:
                rest = runs.rest(m, k, rests)
                if rest is not None and (best is None or value + rest > best[0]):
                    best = (value + rest, key, m)
    assert best is not None, k
    _, key, m = best
    return runs.run(runs.prefix(quiet, k - 1, key) + runs.suffix(m, k, rests))


def _goal_earlier(runs: Runs, rests: list, quiet: list[dict], by_sample: dict[int, Fraction]) -> Loophole | None:
    """A later first goal sample paying more: k2 with the largest G among those beating an earlier
    feasible k (the earliest such), k1 the earliest feasible k < k2 with G(k1) < G(k2)."""
    order = sorted(by_sample)
    lowest: Fraction | None = None
    k2: int | None = None
    for k in order:
        if lowest is not None and by_sample[k] > lowest and (k2 is None or by_sample[k] > by_sample[k2]):
            k2 = k
        lowest = by_sample[k] if lowest is None else min(lowest, by_sample[k])
    if k2 is None:
        return None
    k1 = next(k for k in order if k < k2 and by_sample[k] < by_sample[k2])
    return Loophole("goal_earlier_never_pays_less", _goal_run(runs, rests, quiet, k2),
                    _goal_run(runs, rests, quiet, k1), by_sample[k2] - by_sample[k1], k2, k1)


def _stalling(runs: Runs, rests: list, quiet: list[dict], found: Incentives) -> Loophole | None:
    """Stalling beating a goal run: the latest k with R_stall > G(k); delta makes every k pass."""
    stall = found.stall
    if stall is None:
        return None
    beaten = [k for k, value in found.goal_by_sample.items() if stall.value > value]
    if not beaten:
        return None
    k = max(beaten)
    delta = stall.value - min(found.goal_by_sample[j] for j in beaten)
    return Loophole("stalling_never_pays", stall, _goal_run(runs, rests, quiet, k), delta, k)


def analyse(automaton: ir.Automaton, space: InputSpace, outs: Moves | None = None) -> Findings | Unchecked:
    """The incentives and the loophole checks the automaton's declarations allow (see the module).

    ``outs``: the moves split by :func:`split_guards` when the caller has built them.
    """
    if outs is None or outs.split != split_guards(automaton):
        outs = moves(automaton, space, split_guards(automaton))
    stop = unchecked(automaton, outs)
    if stop is not None:
        return stop
    runs = Runs(automaton, space, outs)
    verdicts: dict[str, Loophole | None] = {}
    rests = runs.safe_rests()
    if automaton.episode_ends is not None:
        anyway = runs.forward(lambda state, m: 0)
        verdicts["ending_early_never_pays"] = _ending_early(runs, rests, anyway)
    if automaton.goal is None:
        return Findings(None, verdicts)
    quiet = runs.forward(lambda state, m: None if m.goal or m.collision else 0)
    found = _incentives(runs, rests, quiet)
    verdicts["goal_earlier_never_pays_less"] = _goal_earlier(runs, rests, quiet, found.goal_by_sample)
    verdicts["stalling_never_pays"] = _stalling(runs, rests, quiet, found)
    return Findings(found, verdicts)


# ---------------------------------------------------------------- diagnostics and facts
#: The warning and the error of each loophole check (the error when a `require` names the check).
CODES = {"ending_early_never_pays": ("W1002", "E1003"), "goal_earlier_never_pays_less": ("W1004", "E1005"),
         "stalling_never_pays": ("W1006", "E1007")}


def check_incentives(automaton: ir.Automaton, space: InputSpace, facts: list[Fact] | None = None,
                     outs: Moves | None = None) -> list[Diagnostic]:
    """The checks of this module as diagnostics (warnings, or errors where a ``require`` names the
    check: E1001 for ``risk``) and facts (p*, and each check proved). Nothing without ``goal when``
    or ``episode ends when``."""
    facts = facts if facts is not None else []
    if automaton.goal is None and automaton.episode_ends is None:
        return []
    found = analyse(automaton, space, outs)
    required = {r.check: r for r in automaton.requirements}
    if isinstance(found, Unchecked):
        return [_unchecked(automaton, found)]
    report = _Report(automaton, space)
    diagnostics: list[Diagnostic] = []
    if found.incentives is not None:
        facts.append(report.risk_fact(found.incentives))
        risk = required.get("risk")
        if risk is not None:
            failure = report.risk_failure(found.incentives, risk)
            if failure is not None:
                diagnostics.append(failure)
    for check, verdict in found.verdicts.items():
        if verdict is None:
            facts.append(report.proved(check, found.incentives))
        else:
            diagnostics.append(report.loophole(verdict, required.get(check)))
    return diagnostics


def _declared(automaton: ir.Automaton, *keys: str) -> Span | None:
    """The span of the first declaration of ``keys`` the file has (else the automaton's name)."""
    for key in keys:
        span = automaton.spans.get(f"decl:{key}")
        if span is not None:
            return span
    return automaton.source.name.span if automaton.source else None


def _unchecked(automaton: ir.Automaton, stop: Unchecked) -> Diagnostic:
    """W1008: the incentive checks were not made (never a verdict)."""
    checks = [name for name, needs in (("risk", automaton.goal), ("ending_early_never_pays", automaton.episode_ends),
                                       ("goal_earlier_never_pays_less", automaton.goal),
                                       ("stalling_never_pays", automaton.goal)) if needs is not None]
    scaling = "scales" in stop.reason
    # a check a `require` asks for is then neither proved nor refuted: the file is undecided
    required = [r.check for r in automaton.requirements if r.check in checks]
    notes = ["they sum a run's return from its samples, exactly, when every update is a translation "
             f"(`r = r + c`) and the horizon has at most {MAX_SAMPLES:,} samples"]
    if required:
        notes.append(f"so {', '.join(f'`require {name}`' for name in required)} "
                     f"{'is' if len(required) == 1 else 'are'} neither proved nor refuted: the file is undecided")
    return warning(
        INCENTIVES_UNDONE, f"the incentive checks ({', '.join(checks)}) not done: {stop.reason}",
        _declared(automaton, "goal", "episode_ends") if scaling else _declared(automaton, "horizon"),
        notes=notes,
        hints=["write the updates as translations to have them checked" if scaling
               else "shorten the horizon or sample less often to have them checked"],
        data={"checks": checks, "reason": stop.reason, "required": required})


def _num(value: Fraction) -> str:
    """A rational as messages show it: exactly when short (``548``, ``0.5``, ``1/3``)."""
    decimal = exact_decimal(value, 6)
    if decimal is not None:
        return decimal
    if abs(value.numerator) < 10**6 and value.denominator < 10**6:
        return f"{value.numerator}/{value.denominator}"
    return short_number(value)


def _p_text(p: Fraction) -> str:
    exact = exact_decimal(p, 10)
    if exact is not None:
        return exact
    shown, rounded = _num(p), short_number(p, 6)
    return shown if shown == rounded else f"{shown} ≈ {rounded}"  # a fraction too long to show is rounded once


class _Report:
    """Messages, notes and data of one automaton's findings."""

    def __init__(self, automaton: ir.Automaton, space: InputSpace) -> None:
        self.automaton, self.space = automaton, space
        named = (automaton.goal, automaton.collision, automaton.episode_ends)
        self.shown: set[str] = set()
        for guard in named:
            if guard is not None:
                self.shown |= guard_inputs(guard)
        self.runs = f"every run of {_num(automaton.horizon)} s ({automaton.steps:,} samples)"

    def time(self, sample: int) -> str:
        return f"t = {_num(sample * self.automaton.period)} s"

    def describe(self, run: Run) -> str:
        ending = ("the episode ends (`episode ends when` holds)" if run.ended_by == "episode"
                  else "the horizon ends the run")
        lines = describe_run(self.automaton, self.space, run.worst, shown=self.shown, ending=ending)
        values, _ = replay(self.automaton, self.space, run.worst)
        listing = ", ".join(f"{r} = {_num(v)}" for r, v in zip(self.automaton.rewards, values))
        return "\n".join([*lines, f"  return {_num(run.value)} ({listing})"])

    def json(self, run: Run | None, samples: dict[str, object] | None = None) -> dict[str, object] | None:
        """A witness for ``--format json``; ``samples``: its ``run`` and ``end`` when moved to replay
        (:meth:`pair_json`), else the run's own."""
        if run is None:
            return None
        if samples is None:
            samples = {"run": run_json(self.automaton, self.space, run.worst),
                       "end": end_json(self.automaton, self.space, run.worst)}
        return {"return": str(run.value), "ended_by": run.ended_by, "goal_sample": run.goal_sample, **samples}

    def returned(self, worst: Worst) -> Fraction:
        """The return of a witness run, replayed exactly."""
        values, _ = replay(self.automaton, self.space, worst)
        objective = self.automaton.objective
        return objective.const + sum((objective.coefficient(r) * v for r, v in zip(self.automaton.rewards, values)),
                                     ZERO)

    def pair_json(self, found: Loophole) -> tuple[dict[str, object] | None, dict[str, object] | None]:
        """The loophole's two runs for ``--format json``, replayable: where a run only approaches a value
        (a supremum), the value moves towards its limit until the runs, replayed exactly, show the claim
        by at least half their gap: the better run's return exceeds the worse run's (docs/checks.md)."""
        gap = found.better.value - found.worse.value
        better, worse = replayable_runs_json(
            self.automaton, self.space, [found.better.worst, found.worse.worst],
            lambda near: self.returned(near[0]) - self.returned(near[1]) >= gap / 2)
        return self.json(found.better, better), self.json(found.worse, worse)

    # ------------------------------------------------------------ p*
    def risk_data(self, found: Incentives) -> dict[str, object]:
        def text(run: Run | None) -> str | None:
            return None if run is None else str(run.value)

        p = found.p_star
        return {"p_star": None if p is None else str(p),
                "p_star_decimal": None if p is None else short_number(p, 10),
                "note": found.p_note, "R_goal": text(found.goal), "R_stall": text(found.stall),
                "R_crash": text(found.crash),
                "witnesses": {"goal": self.json(found.goal), "stall": self.json(found.stall),
                              "crash": self.json(found.crash)}}

    def returns(self, found: Incentives) -> str:
        parts = []
        for name, run in (("R_goal", found.goal), ("R_stall", found.stall), ("R_crash", found.crash)):
            parts.append(f"{name} = {'none' if run is None else _num(run.value)}")
        return ", ".join(parts)

    def risk_fact(self, found: Incentives) -> Fact:
        p = found.p_star
        if p is None:
            head = f"risk tolerance p* undefined: {found.p_note}"
        else:
            head = f"risk tolerance p* = {_p_text(p)}" + (f" ({found.p_note})" if found.p_note else "")
        return Fact("risk", f"{head}; {self.returns(found)} over {self.runs}", self.risk_data(found))

    def risk_failure(self, found: Incentives, requirement: ir.Requirement) -> Diagnostic | None:
        """E1001 when p* exceeds the bound, is undefined for want of a safe goal run, or a crash pays."""
        bound = requirement.bound if requirement.bound is not None else Fraction(0)
        p = found.p_star
        accepted = found.goal is not None and found.crash is not None and found.crash.value >= found.goal.value
        if found.goal is not None and not accepted and (p is None or p <= bound) and (p is None or p < 1):
            return None
        notes: list[Note | str] = []
        hints: list[str] = []
        if found.goal is None:
            message = f"`require risk <= {_num(bound)}` fails: no safe run reaches the goal, so p* is undefined"
            hints.append("check `goal when` and `collision when`: a learner never reaches a goal no safe run reaches")
        elif accepted:
            assert found.crash is not None
            message = (f"`require risk <= {_num(bound)}` fails: a crash pays at least as much as reaching the goal "
                       f"(R_crash = {_num(found.crash.value)} >= R_goal = {_num(found.goal.value)}): any crash "
                       "risk is accepted")
        else:
            assert p is not None
            message = f"`require risk <= {_num(bound)}` fails: the risk tolerance p* = {_p_text(p)} exceeds it"
        for name, run in (("R_goal", found.goal), ("R_stall", found.stall), ("R_crash", found.crash)):
            if run is not None:
                notes.append(f"{name} = {_num(run.value)}:\n{self.describe(run)}")
        if found.goal is not None and found.stall is not None and found.crash is not None and bound > 0:
            # p* <= bound needs R_goal - R_crash >= (R_goal - R_stall) / bound.
            delta = found.crash.value - found.goal.value + (found.goal.value - found.stall.value) / bound
            if delta > 0:
                hints.append(f"make a crash cost at least {_num(delta)} more (objective units; "
                             f"{self.per_reward(delta)}), or shrink what reaching the goal earns over stalling")
        if found.goal is not None:
            notes.insert(0, "p* = (R_goal - R_stall) / (R_goal - R_crash): the largest crash probability a learner "
                            "maximising the return accepts to reach the goal rather than stall")
        return error("E1001", message, requirement.span or _declared(self.automaton, "goal"),
                     notes=notes, hints=hints, data={"bound": str(bound), **self.risk_data(found)})

    def per_reward(self, delta: Fraction, sign: int = -1) -> str:
        """A change of the objective by ``sign * delta`` in each weighted reward's own units (the
        reward lowered or raised by ``delta / |weight|``)."""
        parts = []
        for reward in self.automaton.rewards:
            weight = self.automaton.objective.coefficient(reward)
            if weight:
                way = "raised" if sign * weight > 0 else "lowered"
                parts.append(f"`{reward}` {way} by {_num(delta / abs(weight))} at weight {_num(weight)}")
        return ", or ".join(parts) if parts else "no reward has a weight"

    # ------------------------------------------------------------ the loopholes
    def proved(self, check: str, found: Incentives | None) -> Fact:
        if check == "ending_early_never_pays":
            return Fact(check, "ending early never pays: wherever a run can end without the goal, a safe "
                        f"continuation earns at least as much, over {self.runs}")
        assert found is not None
        if check == "goal_earlier_never_pays_less":
            if not found.goal_by_sample:
                return Fact(check, "reaching the goal earlier never pays less: no safe run reaches the goal")
            samples = sorted(found.goal_by_sample)
            first, last = (found.goal_by_sample[samples[0]], found.goal_by_sample[samples[-1]])
            return Fact(check, "reaching the goal earlier never pays less: G(k), the best return of a safe run "
                        f"first reaching the goal at sample k, never grows with k (k = {samples[0]}..{samples[-1]}, "
                        f"G from {_num(first)} to {_num(last)})",
                        {"G": {str(k): str(found.goal_by_sample[k]) for k in (samples[0], samples[-1])}})
        if found.stall is None:
            return Fact(check, "stalling never beats reaching the goal: every safe run reaches the goal")
        if not found.goal_by_sample:
            return Fact(check, "stalling never beats reaching the goal: no safe run reaches the goal")
        least = min(found.goal_by_sample.values())
        return Fact(check, f"stalling never beats reaching the goal: R_stall = {_num(found.stall.value)} <= G(k) "
                    f"for every k (the least G(k) is {_num(least)})",
                    {"R_stall": str(found.stall.value), "least_G": str(least)})

    def loophole(self, found: Loophole, requirement: ir.Requirement | None) -> Diagnostic:
        a = self.automaton
        code = CODES[found.check][1 if requirement is not None else 0]
        make = error if requirement is not None else warning
        notes: list[Note | str] = []
        delta = _num(found.delta)
        if found.check == "ending_early_never_pays":
            where = (f"in `{a.location_names[found.better.worst.steps[-1].outcome.source]}` at sample "
                     f"{found.sample} ({self.time(found.sample)})")
            message = (f"ending early pays: {where}, ending the run without the goal earns {delta} more than "
                       "the best safe continuation")
            notes += [f"the run that ends early (it ends there without the goal):\n{self.describe(found.better)}",
                      f"the best safe continuation from the same point:\n{self.describe(found.worse)}"]
            hints = [f"penalise ending without the goal by at least {delta} more (objective units; "
                     f"{self.per_reward(found.delta)}); `rac tune` can synthesise the least such penalty "
                     "with a `param` and `require ending_early_never_pays`"]
            declared = _declared(a, "episode_ends")
        elif found.check == "goal_earlier_never_pays_less":
            assert found.other_sample is not None
            message = (f"delaying the goal pays: a safe run first reaching the goal at sample {found.sample} "
                       f"({self.time(found.sample)}) earns {_num(found.better.value)}, {delta} more than the best "
                       f"reaching it at sample {found.other_sample} ({self.time(found.other_sample)})")
            notes += [f"first reaching the goal at sample {found.sample}:\n{self.describe(found.better)}",
                      f"first reaching it at sample {found.other_sample}:\n{self.describe(found.worse)}"]
            hints = [f"make reaching the goal at sample {found.other_sample} pay at least {delta} more: a time "
                     "penalty (a negative rate until the goal), or a goal bonus that shrinks with time; `rac tune` "
                     "can synthesise it with a `param` and `require goal_earlier_never_pays_less`"]
            declared = _declared(a, "goal")
        else:
            message = (f"stalling beats reaching the goal: a safe run that never reaches it earns "
                       f"{_num(found.better.value)}, more than the best reaching it first at sample {found.sample} "
                       f"({_num(found.worse.value)})")
            notes += [f"the run that stalls:\n{self.describe(found.better)}",
                      f"first reaching the goal at sample {found.sample}:\n{self.describe(found.worse)}"]
            hints = [f"raise the goal's bonus by at least {delta} (objective units; "
                     f"{self.per_reward(found.delta, 1)}), "
                     "or lower what stalling earns by as much; `rac tune` can synthesise it with a `param` and "
                     "`require stalling_never_pays`"]
            declared = _declared(a, "goal")
        span = declared
        if requirement is not None and requirement.span is not None:
            span = requirement.span
            if declared is not None:
                notes.insert(0, Note("the condition is declared here", declared))
        better, worse = self.pair_json(found)
        return make(code, message, span, notes=notes, hints=hints,
                    data={"check": found.check, "delta": str(found.delta), "sample": found.sample,
                          "other_sample": found.other_sample,
                          "better": better, "worse": worse})
