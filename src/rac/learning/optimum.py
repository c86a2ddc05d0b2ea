"""The exact optimum of a learning query under a shield: the best return any strategy gets on the
very episodes learning sees (issue 23).

``strategy S = maxE(e)[<=T]{...}->{...}: <> p under safe`` is learned on episodes of a deterministic
model (:class:`rac.learning.episodes.EpisodeBatch`, one step per decision period) whose choices the
shield restricts to a finite set. So its optimum can be computed, not estimated: :func:`solve`

1. **explores the decision graph forward** with the stepping code learning uses: from the start,
   every node (a decision state) is stepped one decision period under each action the shield allows
   there (:func:`rac.learning.strategy.allowed_actions`: the model's ``allow when`` and the shield's
   mask, all of the model's actions where the shield allows none — learning's fallback), each edge
   recording the step's reward as learning receives it (the objective's increase,
   :class:`rac.learning.qlearning.ObjectiveIncrease`; or the batch's own reward). An episode ends at
   the first sample where the goal holds (or the automaton's ``episode ends when``), or at the bound,
   with its ``at end`` clauses: such an edge leads nowhere.
2. **merges the nodes whose episode state is the same** (:meth:`EpisodeBatch.memory`: the sample,
   the sensed state, the automaton's location, the inputs, the previous sample's of each for
   ``prev(e)``) — *without* the accumulated rewards. That is sound when the increments are additive
   along a run: every update a translation ``r = r + c`` (``c`` free of rewards), the objective
   affine in the rewards with constant coefficients, and neither the goal nor a reward function
   reading the rewards (:func:`why_not_additive`). Then two runs in one node differ in their
   rewards by a constant from there on, and the graph is the shielded model times the automaton's
   locations at decision granularity. Otherwise the rewards are part of the node (an enumeration,
   exact too, which merges less): the reason is reported.
3. **solves it backwards**: a node's value is the best (``max`` for ``maxE``, ``min`` for ``minE``)
   of its edges' reward plus the value of their target; ties go to the lowest action index, as
   learning's greedy choices.

The graph is bounded by ``max_states`` decision states and ``max_bytes``
(:class:`rac.engine.budget.Budget`): beyond it :class:`rac.engine.budget.BudgetExceeded`, and the
optimum is out of reach. With ``project=True`` the search also gives up as soon as the decision layers
seen so far project far beyond ``max_states`` by the horizon
(:class:`rac.engine.budget.ProjectionExceeded`): the optimum beside a learned strategy is a reference,
and the layers just before the budget are the costliest to build (every state's shield mask is asked
for; on the tutorial road's 45 actions, 73 s before the budget stopped it at sample 14 of 40).

**Arithmetic.** The rewards are float64, as learning's. The backward pass adds each edge's increment
as one representative run of its node computed it; runs merged into that node would compute it up to
rounding. So the optimum reported is :attr:`Optimum.value`: the return of the optimal strategy's own
run, replayed through the same episodes (:func:`rac.learning.runs.run_strategy`), bit for bit
comparable with a learned strategy's return; :attr:`Optimum.backward` is the backward pass's sum
(they agree to rounding).

**The optimal strategy** (:attr:`Optimum.strategy`) is a :class:`rac.learning.strategy.LearnedStrategy`
over the exact decision state (``time``, the sensed state and the location, unbinned), holding every
node's action values: saved, loaded and run like a learned one, its one run is the optimal run.

Example::

    batch = EpisodeBatch(result, horizon_samples=140)
    best = solve(batch, objective=parse_expr("10*sa + 5*pr + co"), shield=table)
    print(best.value, best.states, best.run.success[0])
"""

from __future__ import annotations

import time
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from rac import ir
from rac.engine.budget import Budget
from rac.engine.shield import ShieldTable
from rac.ir import expr as ie
from rac.learning.episodes import EpisodeBatch, Expression
from rac.learning.qlearning import ObjectiveIncrease
from rac.learning.runs import run_strategy
from rac.learning.strategy import Episodes, LearnedStrategy, StrategyRun, allowed_actions, check_shield
from rac.learning.tabular import STEERED, check_finite

__all__ = ["Optimum", "exploration_text", "observed_state", "shortfall", "solve", "why_not_additive"]

#: The bytes a graph edge costs while exploring (its parent, action, reward, target and flags) besides
#: the key of its target state, which :func:`solve` counts per column.
EDGE_BYTES = 8 * 4 + 4


@dataclass(frozen=True, eq=False)
class Optimum:
    """What :func:`solve` found: the optimum ``value`` (the optimal strategy's replayed return) and
    ``backward`` (the backward pass's value), the optimal ``strategy``, its ``run`` and ``observed``
    expressions, the decision
    ``states`` and ``edges`` of the graph, whether it merged states without their rewards
    (``additive``; else ``why`` not), ``optimise`` (``"max"``/``"min"``) and ``seconds``."""

    value: float
    backward: float
    strategy: LearnedStrategy
    run: StrategyRun
    #: The strategy's observed expressions, checked (:func:`observed_state`).
    observed: tuple[ie.Expr, ...]
    states: int
    edges: int
    additive: bool
    why: str | None
    optimise: str
    seconds: float
    #: The probability that an episode choosing uniformly at random among the allowed actions at
    #: every decision (what ε-greedy learning does at ε = 1, before it has learned anything) reaches
    #: the goal safely (:attr:`rac.learning.strategy.StrategyRun.success`), exact over the same graph.
    uniform_success: float = float("nan")
    #: The same for an episode exploring as :attr:`rac.learning.tabular.Learner.steer` does with
    #: :func:`solve`'s ``steer`` (a share :data:`rac.learning.tabular.STEERED` of the choices take the
    #: allowed action whose ``steer`` is least one decision later, ties uniformly, the others uniform);
    #: None without ``steer``.
    steered_success: float | None = None

    @property
    def expected_first(self) -> float:
        """The episodes a uniformly random explorer needs on average until the first that reaches the
        goal safely, that one included (``1 / uniform_success``: a geometric distribution; ``inf`` when
        none can)."""
        return 1.0 / self.uniform_success if self.uniform_success > 0 else float("inf")

    @property
    def exploration(self) -> str:
        """:attr:`uniform_success` in words, for the reports beside a learned strategy."""
        return exploration_text(self.uniform_success)

    @property
    def method(self) -> str:
        """How the optimum was computed, in words."""
        if self.additive:
            return f"exact, backward pass over {self.states:,} decision states"
        return f"exact, backward pass over {self.states:,} decision states with their rewards ({self.why})"


def exploration_text(chance: float) -> str:
    """What uniform exploration can expect (:attr:`Optimum.uniform_success`), in words: the probability
    that an episode choosing uniformly among the allowed actions reaches the goal safely, and the
    episodes until the first such one on average."""
    if not chance > 0:
        return "no uniformly random episode reaches the goal safely"
    if chance == 1:  # every episode does: "1 episodes on average" said it as though it were a mean
        return "every uniformly random episode reaches the goal safely (exact)"
    return (f"a uniformly random episode reaches the goal safely with probability {100 * chance:.3g} % "
            f"(exact; {1 / chance:.3g} episodes on average until the first)")


def shortfall(learned: float, optimum: float, optimise: str = "max") -> float:
    """How far ``learned`` falls short of ``optimum``, relative to ``|optimum|`` (0: optimal; 0.05:
    5 % worse). For ``minE`` a higher cost falls short. ``inf`` when the optimum is 0 and learned worse."""
    gap = optimum - learned if optimise == "max" else learned - optimum
    if gap <= 0:
        return 0.0
    return gap / abs(optimum) if optimum != 0 else float("inf")


def _affine(expr: ie.Expr) -> bool:
    """Whether ``expr`` is a reward-free term plus constant multiples of rewards (its increments
    along a run do not depend on the rewards held)."""
    if not any(r.kind is ie.RefKind.REWARD for r in ie.refs(expr)):
        return True
    if isinstance(expr, ie.Ref):
        return True
    if isinstance(expr, ie.Unary) and expr.op == "-":
        return _affine(expr.operand)
    if isinstance(expr, ie.Binary):
        if expr.op in ("+", "-"):
            return _affine(expr.left) and _affine(expr.right)
        constant = [side for side in (expr.left, expr.right) if _constant(side)]
        if expr.op == "*" and constant:
            return _affine(expr.right if constant[0] is expr.left else expr.left)
        if expr.op == "/" and _constant(expr.right):
            return _affine(expr.left)
    return False


def _constant(expr: ie.Expr) -> bool:
    form = ie.linear_form(expr)
    return form is not None and form.is_constant


def why_not_additive(automaton: ir.Automaton, *, objective: ie.Expr | None = None, goal: ie.Expr | None = None,
                     reward: ie.Expr | None = None) -> str | None:
    """Why the episodes' rewards cannot be left out of a decision state (None: they can, see the module
    docstring): an update that is not a translation, an objective not affine in the rewards, a goal
    or reward function that reads them. ``objective`` None: the automaton's own (linear)."""
    rewards = set(automaton.rewards)
    found = automaton.first_non_translation()
    if found is not None:
        return f"the update of `{found[0]}` is not `{found[0]} = {found[0]} + c`"
    if any(name in rewards for location in automaton.locations for rate in location.rates
           for name in rate.variables()):
        return "a rate reads the rewards"
    if objective is not None and (not _affine(objective) or any(
            isinstance(node, ie.Prev) and _reads_rewards(node) for node in ie.walk(objective))):
        return "the objective is not affine in the rewards"
    for what, expr in (("the goal", goal), ("the reward function", reward)):
        if expr is not None and _reads_rewards(expr):
            return f"{what} reads the rewards"
    return None


def _reads_rewards(expr: ie.Expr) -> bool:
    return any(r.kind is ie.RefKind.REWARD for r in ie.refs(expr))


def observed_state(automaton: ir.Automaton) -> tuple[str, ...]:
    """The optimal strategy's observation: the decision state exactly (``time``, the sensed state and
    the automaton's location, as they are)."""
    return ("time", "x", "y", "v", "acc", "head", "jerk", "turn", f"{automaton.name}.location")


@dataclass(frozen=True, eq=False)
class _Layer:
    """The edges out of one layer of decision states (sorted by parent, then action)."""

    parent: np.ndarray
    action: np.ndarray
    reward: np.ndarray
    target: np.ndarray  # the next layer's node, -1 where the episode ended
    observed: np.ndarray  # (nodes, len(observed_state)): the layer's nodes observed
    safe: np.ndarray  # the step neither collided nor left the road
    arrived: np.ndarray  # the episode ended at the goal, in a state from which it can stay safe
    toward: np.ndarray | None  # the edge is among its parent's least ``steer`` after it (None: no steer)


def solve(batch: EpisodeBatch, *, objective: Expression | None = None, optimise: str = "max",
          shield: ShieldTable | None = None, max_states: int | None = None, max_bytes: int | None = None,
          meta: Mapping[str, object] | None = None, project: bool = False,
          progress: Callable[[int, int, int], None] | None = None, steer: Expression | None = None) -> Optimum:
    """The optimum of ``maxE``/``minE`` (``optimise``) of the episodes' return on ``batch`` under
    ``shield`` (see the module docstring). ``objective``: reward each step with the increase of this
    expression (:class:`rac.learning.qlearning.ObjectiveIncrease`, as ``rac verify`` learns); None:
    the batch's own reward. ``batch`` is used up (its episodes are replaced). ``meta``: stored with
    the optimal strategy. :class:`rac.engine.budget.BudgetExceeded` beyond ``max_states`` decision
    states or ``max_bytes``; with ``project``, :class:`rac.engine.budget.ProjectionExceeded` as soon as
    the layers so far project beyond it (:meth:`rac.engine.budget.Budget.check_projection`). ``progress(sample,
    layer states, states)`` after each layer of decision states, as an exploration's (a bar, a time limit's check,
    which may raise); it changes nothing computed. ``steer``: also the chance of an episode exploring as
    :attr:`rac.learning.tabular.Learner.steer` does with it (:attr:`Optimum.steered_success`)."""
    if optimise not in ("max", "min"):
        raise ValueError(f"optimise must be 'max' or 'min', not {optimise!r}")
    check_shield(batch, shield)
    t0 = time.perf_counter()
    checked = None if objective is None else batch.expression(objective)
    why = why_not_additive(batch.automaton, objective=checked, goal=batch.goal, reward=batch.reward_expr)
    scored: Episodes = batch if checked is None else ObjectiveIncrease(batch, checked)
    names = observed_state(batch.automaton)
    exprs = [batch.expression(name) for name in names]
    steered = None if steer is None else batch.expression(steer)
    budget = Budget(max_states=max_states, max_bytes=max_bytes,
                    what="the decision graph of the shielded episodes", period=float(batch.automaton.period))
    layers: list[_Layer] = []
    sizes = [1]  # the decision states per layer, for the projection
    states, edges, stored = 1, 0, 0
    scored.reset(1)
    for step in range(batch.max_steps):
        observed = batch.observe(exprs)
        if step + 1 < batch.max_steps:
            # The next layer has at most one state per (state, action) pair the model allows: checked
            # before the shield is asked about them (an on-demand shield proves every pair; on the
            # tutorial's 45 actions, a layer of a million states took minutes and 6.7 GB before
            # check_states below refused the layer after it).
            bound = states + int(batch.model_masks().sum())
            budget.check_states(bound, int(batch.k.max()) + batch.decide_every)
        masks, _empty = allowed_actions(scored, shield)
        parent, action = np.nonzero(masks)  # by parent, then action: the lowest action first
        sample = int(batch.k.max())
        budget.check_bytes(stored + parent.size * (EDGE_BYTES + 8 * observed.shape[1]), states, sample)
        batch.select(parent)
        outcome = scored.step(action.astype(np.int64))
        live = ~np.asarray(batch.done, dtype=bool)
        target = np.full(parent.size, -1, dtype=np.int64)
        keys = batch.memory(rewards=why is not None)
        edges += parent.size
        if live.any():
            unique, first, inverse = np.unique(keys[live], axis=0, return_index=True, return_inverse=True)
            target[live] = inverse.reshape(-1)
            states += unique.shape[0]
            sizes.append(unique.shape[0])
            budget.check_states(states, sample + batch.decide_every)
            if project:  # a layer per decision; the last layer of live states is max_steps - 1
                budget.check_projection(sizes, 1, batch.max_steps - 1, sample + batch.decide_every,
                                        horizon_sample=batch.horizon_samples)
            stored += parent.size * EDGE_BYTES + unique.shape[0] * 8 * (keys.shape[1] + len(exprs))
            budget.check_bytes(stored, states, sample + batch.decide_every)
            if progress is not None:
                progress(sample + batch.decide_every, unique.shape[0], states)
        toward = None
        if steered is not None:  # the learner's lookahead reads the expression after the step, as here
            after_step = batch.observe([steered])[:, 0]
            after_step = np.where(np.isnan(after_step), np.inf, after_step)
            least = np.full(int(parent.max()) + 1, np.inf)
            np.minimum.at(least, parent, after_step)
            toward = after_step == least[parent]
        reward = np.asarray(outcome.reward, dtype=np.float64)
        check_finite(reward)  # learning refuses it too; the backward pass would compute on NaN
        layers.append(_Layer(parent, action, reward, target, observed,
                             ~(np.asarray(outcome.collided, dtype=bool) | np.asarray(outcome.offroad, dtype=bool)),
                             np.asarray(outcome.terminated, dtype=bool) & ~np.asarray(outcome.stranded, dtype=bool),
                             toward))
        if not live.any():
            break
        batch.select(np.flatnonzero(live)[first])
    else:
        raise RuntimeError("episodes went on past their last step")  # max_steps covers the horizon
    sign = 1.0 if optimise == "max" else -1.0
    # Backwards: a node's value is its best edge's reward plus its target's value (0 where the episode ends).
    after = np.zeros(0)
    chance = np.zeros(0)  # per node of the layer after: a uniformly random continuation's chance of success
    steered_chance = np.zeros(0)  # the same, exploring as the learner's steer does
    best: list[np.ndarray] = []
    q_values: list[np.ndarray] = []
    for layer in reversed(layers):
        q = layer.reward + np.where(layer.target >= 0, after[np.maximum(layer.target, 0)] if after.size else 0.0, 0.0)
        nodes = layer.observed.shape[0]
        onward = np.where(layer.target >= 0, chance[np.maximum(layer.target, 0)] if chance.size else 0.0,
                          layer.arrived.astype(np.float64))
        counts = np.maximum(np.bincount(layer.parent, minlength=nodes), 1)
        if layer.toward is not None:
            edge = np.where(layer.safe, np.where(layer.target >= 0, steered_chance[np.maximum(layer.target, 0)]
                                                 if steered_chance.size else 0.0, layer.arrived.astype(np.float64)),
                            0.0)  # per edge: a steered continuation's chance after it
            towards = np.bincount(layer.parent, weights=edge * layer.toward, minlength=nodes) / np.maximum(
                np.bincount(layer.parent, weights=layer.toward, minlength=nodes), 1)
            steered_chance = STEERED * towards + (1 - STEERED) * np.bincount(layer.parent, weights=edge,
                                                                             minlength=nodes) / counts
        chance = np.bincount(layer.parent, weights=np.where(layer.safe, onward, 0.0), minlength=nodes) / counts
        top = np.full(nodes, -np.inf)
        np.maximum.at(top, layer.parent, sign * q)
        hits = np.flatnonzero(sign * q == top[layer.parent])
        _, first_hit = np.unique(layer.parent[hits], return_index=True)  # the lowest action of the best
        choice = np.zeros(nodes, dtype=np.int64)
        choice[layer.parent[hits[first_hit]]] = hits[first_hit]
        best.append(choice)
        q_values.append(q)
        after = sign * top
    best.reverse()
    q_values.reverse()
    strategy = _strategy(batch, layers, best, q_values, names, sign, optimise,
                         dict(meta or {}, exact=True, optimum=float(after[0]), decision_states=states,
                              additive=why is None))
    run = run_strategy(scored, strategy, exprs=exprs, shield=shield)
    return Optimum(float(run.returns[0]), float(after[0]), strategy, run, tuple(exprs), states, edges, why is None,
                   why, optimise, time.perf_counter() - t0, float(chance[0]),
                   None if steered is None else float(steered_chance[0]))


def _strategy(batch: EpisodeBatch, layers: Sequence[_Layer], best: Sequence[np.ndarray],
              q_values: Sequence[np.ndarray], names: tuple[str, ...], sign: float, optimise: str,
              meta: dict[str, object]) -> LearnedStrategy:
    """The optimal strategy as a table over the observed decision states: every node's action values
    (the edge's reward plus its target's value; ``-inf`` in the maximised sense for an action not
    taken there). Two nodes observed alike (they differ in the previous sample or the inputs only)
    share a row: the optimal run's node keeps it, so the strategy's one run is the optimal run."""
    keys, values = [], []
    on_path: int | None = 0  # the optimal run's node in the current layer (None: the run has ended)
    for depth, layer in enumerate(layers):
        nodes = layer.observed.shape[0]
        table = np.full((nodes, batch.n_actions), -np.inf)
        table[layer.parent, layer.action] = sign * q_values[depth]
        order = np.arange(nodes)
        if on_path is not None:  # the run's node first: np.unique keeps the first of equal rows
            order = np.concatenate([[on_path], np.delete(order, on_path)])
            target = int(layer.target[best[depth][on_path]])
            on_path = target if target >= 0 else None
        _, first = np.unique(layer.observed[order], axis=0, return_index=True)
        rows = order[np.sort(first)]
        keys.append(layer.observed[rows])
        values.append(sign * table[rows])  # the objective's sense: costs for minE
    return LearnedStrategy(names, (), (), optimise, np.concatenate(keys) + 0.0, np.concatenate(values),
                           np.array(batch.action_pairs), meta)
