"""``rac verify``'s check of penalties that no action avoids (issue 25): W1011.

A penalty that every action incurs teaches nothing: when traffic spawns inside the unsafe distance
at the first sample, every action is followed by the unsafe location, and the learner cannot tell
the actions apart by it (Knox et al., "Reward (Mis)design for Autonomous Driving"; found by hand on
highway-env). :func:`check_penalties` explores the product of model and automaton and asks
:func:`rac.engine.penalties.unavoidable` for the decision states where every choice ``allow when``
permits is followed by a location that penalises an objective.

**Which penalty.** P2's, from its owner :func:`rac.check.analysis.priority.p2_target` (``watched``):
a location penalises ``o`` when ``o``'s rate there can be negative or an edge into it lowers ``o``.
The objectives are the ``priority`` order's rewards; without one, the rewards the objective weighs
positively (each asked of P2's notion as if it were the highest priority). Why the location after
the step and not the objective's increase over it: :mod:`rac.engine.penalties`.

**Out of reach.** The check explores within its own state budget (:data:`PENALTY_STATES`, or
``--max-states`` when smaller). When the product up to the horizon is larger, the product is
explored as far as the budget allows and the decisions whose samples it covers are checked; the
result says how far. When not even the first decision fits, the check says it was not done.

Example::

    context, results = run_queries(compile_file("model.ra"))
    check = check_penalties(context)
    print(render_penalties(check))
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field
from fractions import Fraction

from rac import ir
from rac.check.analysis.priority import p2_target
from rac.core.diagnostics import Diagnostic, Note, counted, warning
from rac.engine.budget import BudgetExceeded, TimeExceeded, TimeLimit
from rac.engine.evaluate import EvaluationError
from rac.engine.penalties import Unavoidable, choice_penalties, unavoidable
from rac.engine.product import ProductGraph, explore_product
from rac.ir.significands import Unrepresentable
from rac.ir.vocabulary import EGO_STATE
from rac.model.data import ModelRangeError
from rac.verify.context import Context
from rac.verify.report import format_number

__all__ = ["PENALTY_STATES", "PenaltyCheck", "check_penalties", "penalised_locations", "render_penalties"]

#: The check's own state budget (``--max-states`` when smaller): it runs on every ``rac verify`` without ``--query``, so
#: it may cost a fraction of what the queries may (the spawn it looks for shows at the first samples).
PENALTY_STATES = 50_000
#: The actions a W1011 note lists before it says "and N more".
SHOWN_ACTIONS = 9


@dataclass(frozen=True)
class PenaltyCheck:
    """The check's outcome: ``done`` (False: out of reach, ``message`` says why), the W1011
    ``diagnostics`` (one per objective with such states), and the line ``rac verify`` prints."""

    done: bool
    message: str
    diagnostics: tuple[Diagnostic, ...] = ()
    #: The samples whose decisions were checked, of ``horizon_samples`` (fewer: the budget cut it).
    samples: int = 0
    horizon_samples: int = 0
    #: The product's states and the decision states judged.
    states: int = 0
    decisions: int = 0
    #: Objective -> the number of decision states where every allowed action is penalised.
    counts: dict[str, int] = field(default_factory=dict)

    def to_json(self) -> dict[str, object]:
        """``rac verify --format json``'s ``penalties``."""
        return {"done": self.done, "message": self.message, "samples": self.samples,
                "horizon_samples": self.horizon_samples, "states": self.states, "decisions": self.decisions,
                "unavoidable": dict(self.counts), "diagnostics": [d.to_json() for d in self.diagnostics]}


def penalised_locations(automaton: ir.Automaton) -> dict[str, tuple[bool, ...]]:
    """Per objective, the locations that penalise it (P2's notion, :func:`p2_target`'s ``watched``):
    the ``priority`` order's rewards, or without one the rewards the objective weighs positively."""
    if automaton.priority:
        return {reward: p2_target(automaton, level).watched for level, reward in enumerate(automaton.priority)}
    # P2's owner reads the reward at the top of the order: ask it of each reward as the only one
    return {reward: p2_target(dataclasses.replace(automaton, priority=(reward,)), 0).watched
            for reward in automaton.rewards if automaton.objective.coefficient(reward) > 0}


def check_penalties(context: Context, max_states: int | None = None) -> PenaltyCheck:
    """Penalties that no action avoids in the context's model and automaton, up to its horizon
    (explored within ``max_states``, default the smaller of :data:`PENALTY_STATES` and the options')."""
    automaton, horizon = context.automaton, context.horizon_samples
    penalised = {o: mask for o, mask in penalised_locations(automaton).items() if any(mask)}
    if not penalised:
        return PenaltyCheck(True, "no location penalises an objective (no negative rate, no edge lowering one): "
                            "nothing to avoid", horizon_samples=horizon)
    budget = max_states if max_states is not None else min(PENALTY_STATES, context.options.max_states)
    graph, samples, reason = _explore(context, horizon, budget)
    every = context.data.decide_every
    # a decision at sample k holds up to k + decide_every: checked when those samples are explored
    before = None if samples == horizon else samples - every + 1
    if graph is None or (before is not None and before <= 0):
        return PenaltyCheck(False, f"not checked: {reason}", horizon_samples=horizon)
    found = unavoidable(graph, penalised, before=before)
    decisions = max(u.decisions for u in found.values())
    counts = {o: int(u.states.size) for o, u in found.items() if u.states.size}
    reach = (f"up to the horizon ({counted(horizon, 'sample')})" if before is None else
             f"in the first {counted(samples, 'sample')} of {horizon} ({reason}: later decisions are not "
             "checked)")
    names = ", ".join(f"`{o}`" for o in penalised)
    if not counts:
        message = (f"none: at each of the {counted(decisions, 'decision state')} {reach} some allowed action "
                   f"avoids every penalty of {names}")
    else:
        message = "; ".join(f"every allowed action is penalised (`{o}`) in {counted(n, 'decision state')}"
                            for o, n in counts.items()) + f" {reach} (W1011)"
    diagnostics = tuple(_warning(context, graph, u, penalised[o]) for o, u in found.items() if u.states.size)
    return PenaltyCheck(True, message, diagnostics, samples=samples, horizon_samples=horizon,
                        states=graph.n_states, decisions=decisions, counts=counts)


def _explore(context: Context, horizon: int, budget: int) -> tuple[ProductGraph | None, int, str]:
    """The complete product up to ``horizon``, or, beyond the budget, up to the last sample within
    it; the samples explored and why fewer than the horizon (None and the reason: none explored)."""
    samples, reason = horizon, ""
    # --max-seconds holds for this check as for a query (the last query's limit, maybe passed, is not its own)
    context.limit = TimeLimit(context.options.max_seconds, what="the penalty check")
    while samples > 0:
        try:
            return explore_product(context.data, context.automaton, horizon_samples=samples, max_states=budget,
                                   max_bytes=context.memory_left(),
                                   progress=context.explore_progress), samples, reason
        except BudgetExceeded as exc:
            if exc.kind == "states":
                limit = "--max-states" if budget < PENALTY_STATES else "the check's own budget"
                reason = f"by sample {exc.sample} the product has more than {counted(budget, 'state')}, {limit}"
            else:
                reason = f"{exc}{context.kept_note()}"
            samples = min(samples - 1, exc.sample - 1)
        except TimeExceeded as exc:
            return None, 0, f"{exc} (--max-seconds)"
        except (ModelRangeError, EvaluationError, Unrepresentable) as exc:
            return None, 0, f"the product cannot be explored: {exc}"
    return None, 0, reason or "the horizon has no sample"


def _warning(context: Context, graph: ProductGraph, found: Unavoidable, mask: tuple[bool, ...]) -> Diagnostic:
    """W1011 for one objective: how many states, the first one, its actions, and what to do."""
    automaton, data = context.automaton, context.data
    first = found.first
    assert first is not None
    scale = float(data.scale)
    k = int(graph.k[first])
    time = Fraction(k) * context.period
    ego = {name: int(graph.ego[first, i]) / scale for i, name in enumerate(EGO_STATE)}
    choices = graph.choices(first)
    locations = choice_penalties(graph, mask)[choices.start:choices.stop]
    entered = sorted({automaton.location_names[int(loc)] for loc in locations})
    pairs = context.pairs[graph.choice_action[choices.start:choices.stop]] / scale
    shown = ", ".join(f"({format_number(j)}, {format_number(t)})" for j, t in pairs[:SHOWN_ACTIONS])
    more = f" and {len(pairs) - SHOWN_ACTIONS} more" if len(pairs) > SHOWN_ACTIONS else ""
    allowed = (f"all {len(pairs)}" if len(pairs) == len(context.pairs)
               else f"the {len(pairs)} of {len(context.pairs)} that `allow when` permits")
    by = Fraction(k + data.decide_every) * context.period
    where = ", ".join(f"`{name}`" for name in entered)
    state = (f"x = {format_number(ego['x'])} m, y = {format_number(ego['y'])} m, v = {format_number(ego['v'])} m/s, "
             f"heading {format_number(ego['head'])} rad")
    notes = [
        f"the first: t = {format_number(float(time))} s (sample {k}), the ego at {state}; each of its actions "
        f"({allowed}, (jerk, turn): {shown}{more}) leads into {where}, which penalises `{found.objective}`, "
        f"by t = {format_number(float(by))} s",
        "a penalty every action incurs teaches nothing: the learner cannot tell the actions apart by it",
    ]
    if k == 0:
        hint = ("the scenario starts the ego where the penalty cannot be avoided (traffic spawning inside the "
                "unsafe distance?): move the ego's start or the traffic, start the penalty later (a guard on "
                "an input bound to `time`), or leave the first samples out of training")
    else:
        hint = ("earlier decisions lead into states where the penalty cannot be avoided: if no run should, "
                "move the scenario's traffic or the ego's start; otherwise a shield (`strategy S = control: A[] "
                "...`) keeps the learner out of them")
    span = automaton.spans.get("model:scenario") or (automaton.model.span if automaton.model else None)
    first_data = {"sample": k, "time": float(time), **ego, "locations": entered,
                  "actions": [[float(j), float(t)] for j, t in pairs]}
    return warning(
        "W1011", f"every allowed action is penalised (`{found.objective}`) in "
        f"{counted(int(found.states.size), 'decision state')} from t = {format_number(float(time))} s",
        span, notes=[Note(n) for n in notes], hints=[hint],
        data={"objective": found.objective, "states": int(found.states.size), "first": first_data})


def render_penalties(check: PenaltyCheck) -> str:
    """The lines ``rac verify`` prints after the queries (the W1011 warnings are rendered apart)."""
    lines = ["Checking penalties that no action avoids", f" -- {check.message}"]
    if check.done and check.states:
        lines.append(f"    {counted(check.states, 'state')}, horizon {check.samples} samples")
    return "\n".join(lines)
