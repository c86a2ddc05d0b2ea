"""``rac experiment``: the paper's Table 2 — learning with and without a shield, with a reward
automaton or a reward function — on the user's own scenario, repeated over seeds.

Four combinations, as in the paper (Section 6):

- **SS&RA** — safety shield + reward automaton: the reward is the automaton's objective increase
  per sample (plus its ``at end`` bonus), actions are restricted to the shield's;
- **SS&RF** — safety shield + reward function: a plain function of the current inputs and model
  (default: the paper's Eq. 9, ``10*!isClose + (5 + 100*goal())*prog + comf``);
- **RA** — the automaton alone; **RF** — the reward function alone.

As UPPAAL's ``maxE(e)``, learning maximises the value of ``e`` when an episode ends (the goal is
reached, or the horizon): each step is rewarded with the increase of ``e``. With the automaton,
``e`` is its objective over accumulating rewards, so every sample carries a signal; with the
reward function only the last state's value counts. That is the difference the paper measures.

Each combination learns by tabular Q-learning (:func:`rac.learning.qlearning.learn`) over the same
observation (the file's first learning query's lists, or the automaton's location and
``x, y, v, head``) for every seed. Measured per run: the learning time, the episodes until the
greedy strategy first reaches the goal without a collision or leaving the road, the collisions
during learning (episodes with at least one), and the final strategy's success — its greedy run
(the model is deterministic: one run), and 100 evaluation runs in which each decision is random
with probability 0.1 (how well the strategy recovers from deviations; under the shield the
random actions are the shield's). The shield is computed once (its time is reported apart, as in
the paper's table).

Beside each shielded combination's greedy return stands the exact optimum under the shield: the best
return any strategy gets on the same episodes with the same reward (:func:`rac.learning.optimum.solve`,
a backward pass over the shielded decision graph), computed once per combination, and each seed's
shortfall from it (``(optimum - learned) / |optimum|``). Where the graph is out of reach (the
``max_states`` budget) the report says so and the learning results stand alone.

All runs learn together in one batch of episodes (:mod:`rac.learning.lockstep`; issue 11): each
run's results are the ones it has alone, and its learning time is its own computation plus its
share of the batch's steps (by its episodes still running).
"""

from __future__ import annotations

import dataclasses
import errno
import math
import os
import time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import IO, Any

import numpy as np

from rac.compiler import CompileResult
from rac.core.diagnostics import CheckError, Diagnostic, RacError, RacValueError, counted, error, json_text
from rac.core.files import atomic_write
from rac.engine.budget import (
    BudgetExceeded,
    EstimateExceeded,
    check_estimate,
    evaluation_bytes,
    learning_bytes,
    out_of_memory,
)
from rac.ir import query as iq
from rac.learning.episodes import EpisodeBatch, parse_expr

__all__ = ["ABLATION", "COMBINATIONS", "GROWTH", "PAPER_INPUTS", "PAPER_REWARD_FUNCTION", "ExperimentError", "Options",
           "Report", "default_reward_problem", "default_widths", "goal_out_of_reach", "render_ablation",
           "render_markdown", "results_json", "run_experiment", "write_outputs"]

#: The experiment's report and its summary rows (JSON-shaped: written as JSON and as Markdown).
Report = dict[str, Any]

#: The paper's Eq. 9 with its ``safe`` written as ``!isClose``.
PAPER_REWARD_FUNCTION = "10 * !isClose + (5 + 100 * goal()) * prog + comf"
#: The inputs :data:`PAPER_REWARD_FUNCTION` reads.
PAPER_INPUTS = ("isClose", "prog", "comf")


def default_reward_problem(inputs: Iterable[str]) -> str | None:
    """Why the paper's reward function (the default of ``--reward-function``) cannot serve an automaton
    with these inputs, for the user; None when it can."""
    if set(PAPER_INPUTS) <= set(inputs):
        return None
    return (f"the default reward function (the paper's Eq. 9) reads the inputs {', '.join(PAPER_INPUTS[:-1])} "
            f"and {PAPER_INPUTS[-1]}; pass --reward-function EXPR for this automaton")


#: (label, shielded, reward kind) in the paper's order.
COMBINATIONS: tuple[tuple[str, bool, str], ...] = (
    ("SS&RA", True, "automaton"), ("SS&RF", True, "function"), ("RA", False, "automaton"), ("RF", False, "function"))
#: Probability of a random action in the evaluation runs.
EVALUATION_NOISE = 0.1
#: Batches grow with the episodes learned: ``ceil(GROWTH * learned)`` episodes, at least 1, at most
#: ``parallel``; the greedy strategy is evaluated after each batch, so "episodes until the first
#: safe goal" is measured to within a quarter early on (after 1, 2, 3, 4, 5, 7, 9, 12, 15 ... episodes).
GROWTH = 0.25
#: The ablation's rows (SS&RA, every seed): what the experiment used, then the observation's bins
#: swapped (derived <-> the fixed defaults, or --bins <-> the fixed defaults), counterfactual
#: experiences switched, the backward replay switched, all three at once, the decision time not
#: observed, the earlier learner (:data:`EARLIER`), and the best episode not replayed.
ABLATION = ("as the experiment", "other bins", "counterfactuals switched", "replay switched", "all three switched",
            "time not observed", "untried actions at 0", "best episode not replayed")
#: The learner of every combination (issue 23): the model is deterministic and the decision index is
#: observed, so ``alpha=1`` makes a tried table entry the best return seen after it; untried actions
#: are never preferred to tried ones (``pessimistic``), so the greedy strategy is the best run seen;
#: and the best learning episode seen is replayed after every batch (``replay_best``): the binned
#: continuous observations let two states share a key, a later, worse run through it overwrote the
#: best run's values, and the greedy strategy reached the goal only batches after a learning episode
#: had (on examples/paper, seed 6: the first safe episode at 10, the greedy strategy's first safe goal
#: at 60). Exploration is epsilon's alone, uniform among the allowed actions, from 1 down to 0.2 over
#: the budget, ties broken at random in the learning episodes. (Tried on examples/paper and not
#: kept: a lower or faster decaying epsilon, one or two deviations per episode from the greedy run,
#: sticky or least-tried exploring actions and Go-Explore restarts all found the first safe goal
#: later than uniform exploration — the dense rewards do not lead to the goal bonus: the best
#: failing runs begin down branches that rarely reach it, and of the two first actions the shield
#: allows one never leads to the goal (0 of 2,029 uniform episodes); UCT on the normalised mean
#: returns found it sooner on seeds 1-10 but not on 11-20, and ended further from the optimum;
#: a potential over the goal distance, epsilon at 1 until the first safe goal and then lower, both
#: within the seeds' spread; docs/learning.md has the figures. Potential-based shaping over the
#: automaton's locations cannot change this learner's choices: with gamma=1 every run from a state
#: gains the same -phi(state).) What did help is knowledge of the model: ``--explore goal`` (:data:`EXPLORE`)
#: steers half the exploring choices towards the goal by looking one decision ahead, for every combination;
#: it is an option, not the default, so that the default tables stay those of a model-free explorer.
#: "untried actions at 0" in the ablation is the learner before (``EARLIER``).
LEARNER: dict[str, Any] = {"alpha": 1.0, "epsilon": (1.0, 0.2), "pessimistic": True, "random_ties": True,
                           "replay_best": True}
#: How the learning episodes explore (``--explore``): the expression half the exploring choices make
#: least one decision later, by looking ahead in the model (:attr:`rac.learning.tabular.Learner.steer`),
#: or None: uniformly among the allowed actions (the default, as every table before it). On
#: examples/paper, heading for the goal half the time raises the chance that an exploring episode under
#: the shield reaches it safely from 2.61 % to 8.66 % (exact: the notes of ``rac experiment --explore goal``);
#: without the shield RA, which exploring uniformly got there in 4 of 5 seeds, did in none (docs/learning.md).
#: The command line's choices (rac.cli.arguments) are these names; a test holds them equal.
EXPLORE: dict[str, str | None] = {"uniform": None, "goal": "dist_goal()"}
#: The learner before issue 23's second round: untried entries 0, ``alpha=0.3``, epsilon down to
#: 0.05, ties to the lowest index (the ablation's "untried actions at 0").
EARLIER: dict[str, Any] = {"alpha": 0.3, "epsilon": (1.0, 0.05), "pessimistic": False, "random_ties": False}


class ExperimentError(RacError, ValueError):
    """The experiment cannot run on this file (no model, no goal, an unusable reward function).

    ``kind`` says whose it is, for the command's exit code: ``"usage"`` (an option to change:
    ``--bins``, ``--reward-function``), ``"limit"`` (beyond ``--max-states`` or the memory budget),
    ``"model"`` (the file: no ``model`` block, no safe strategy, learning that failed)."""

    def __init__(self, message: str, kind: str = "model", diagnostic: Diagnostic | None = None,
                 states: int | None = None) -> None:
        super().__init__(message)
        self.kind = kind
        #: The safety shield's states when it was computed before the experiment stopped (no safe strategy), else None.
        self.states = states
        if diagnostic is not None:  # the failure points into the file (a query's observation)
            self.diagnostic = diagnostic


@dataclass(frozen=True)
class RunRecord:
    """One combination and seed."""

    combination: str
    seed: int
    seconds: float
    episodes: int
    first_success_episode: int | None
    collisions_during_learning: int
    offroad_during_learning: int
    greedy_success: bool
    evaluation_successes: int
    evaluation_runs: int
    returns: np.ndarray
    succeeded: np.ndarray  # per learning episode: goal reached safely
    greedy_return: float = float("nan")  # the final greedy strategy's return (its one run)
    optimum: float | None = None  # the exact optimum of the combination under the shield (None: none)
    counterfactuals: bool = False


def _with_time(discrete: Sequence[str]) -> list[str]:
    """The discrete observations with the decision time (``time``) added when it is not among them.

    An episode is a finite-horizon problem whose obstacles move with time, whose goal may have a
    time window and which ends at the horizon: the same place and speed at two decision times are
    two states with different futures (waiting for a crossing car at 4 s is not waiting at 8 s),
    and the optimal strategy depends on the time. Without it in the observation, Q-learning averages
    the two futures (the observation is not Markov); with it, the decision states form a tree
    (depth: the decisions per episode) on which Q-learning with ``alpha=1`` is exact where visited."""
    return [*discrete] if "time" in discrete else [*discrete, "time"]


def _observed_from(report: Mapping[str, Any]) -> str:
    """Where the observation comes from, and that the rest of the file's learning query is not used."""
    query = report["observation"].get("query")
    if query is None:
        return "the file has no learning query: the paper's observation."
    return (f"the lists of query `{query}`, and only those: every combination learns its own reward towards "
            f"`goal()` over this horizon, whatever that query's objective, goal and bound (`rac verify --query "
            f"{query}` answers it as written).")


def _learning_query(result: CompileResult) -> iq.QueryDecl | None:
    """The file's first learning query, whose observation lists the experiment takes (None: none)."""
    assert result.automaton is not None
    return next((decl for decl in result.automaton.queries if isinstance(decl.query, iq.LearnStrategy)), None)


def _learning_spec(result: CompileResult) -> tuple[list[str], list[str], str | None]:
    """The observation lists (as text) of the file's first learning query and its name, or the
    paper's defaults and None."""
    automaton = result.automaton
    assert automaton is not None
    decl = _learning_query(result)
    if decl is not None:
        assert isinstance(decl.query, iq.LearnStrategy)
        count = len(decl.query.discrete)
        return list(decl.query.labels[:count]), list(decl.query.labels[count:]), decl.name
    return [f"{automaton.name}.location"], ["x", "y", "v", "head"], None


def _check_counterfactual_observation(result: CompileResult, ablation: bool) -> None:
    """ExperimentError, pointing at the file's learning query, when its observation cannot serve
    counterfactual experiences (:func:`rac.learning.qlearning.location_column`): said before the shield
    and the optimum are computed, not by the learning after them, and as the query's fault."""
    # stormpy (via rac.learning.qlearning): importing rac.studies.experiment stays light
    from rac.learning.qlearning import ObservationError, location_column

    decl = _learning_query(result)
    if decl is None:  # the paper's observation: the location and x, y, v, head
        return
    query = decl.query
    assert isinstance(query, iq.LearnStrategy)
    try:
        location_column(query.discrete, query.continuous)
    except ObservationError as exc:
        observations = (*query.discrete, *query.continuous)
        span = decl.span if exc.index is None else observations[exc.index].span or decl.span
        assert result.automaton is not None
        fix = (f"add `{result.automaton.name}.location` to its discrete list" if exc.index is None else
               f"leave `{query.labels[exc.index]}` out of its lists")
        hint = (f"{fix} (--ablation learns SS&RA with counterfactual experiences and without)" if ablation else
                f"{fix}, or pass --no-counterfactuals (the automaton's combinations then learn without them)")
        message = f"the observation of query `{decl.name}`, which rac experiment learns on: {exc}"
        raise ExperimentError(message, diagnostic=error("E0015", message, span, hints=[hint])) from None


def _shield(result: CompileResult, horizon_samples: int, max_states: int, needed: bool,
            max_bytes: int | None = None, explore_progress: Callable[[int, int, int], None] | None = None):
    """The safety shield's table (None when ``needed`` is false and no safe strategy exists from the
    start), the seconds it took, its states, and the judge of "safe to the horizon" from a goal state
    (:class:`rac.engine.shield.SafeOnward`); ExperimentError when the shield is needed and absent.
    ``explore_progress``: the exploration's per-layer callback (the states counted so far)."""
    # stormpy (via rac.engine.shield): importing rac.studies.experiment stays light
    from rac.engine import shield as shields
    from rac.verify.context import over_budget  # beside it (it imports the shield too): a refusal in the options' words

    data = result.model_data
    assert data is not None
    t0 = time.perf_counter()
    try:
        computed, table = shields.synthesise(data, horizon_samples, max_states=max_states, max_bytes=max_bytes,
                                             progress=explore_progress)
    except MemoryError as exc:
        # the budget's own refusal says which limit stopped it; the process's memory running out first (a
        # `ulimit -v`, a container) said only numpy's "Unable to allocate 80.0 MiB", with no limit named
        if isinstance(exc, BudgetExceeded) and not isinstance(exc, EstimateExceeded):
            # with what to raise: --max-states, or the memory option of the command (rac sweep's --task-memory);
            # it named only what to coarsen, the memory option only as the budget
            raise ExperimentError(f"the safety shield cannot be computed: {over_budget(exc)}", "limit") from None
        why = str(exc) if isinstance(exc, RacError) else out_of_memory(exc, "computing it")
        raise ExperimentError(f"the safety shield cannot be computed: {why}; coarsen the model (actions, "
                              "decide_period) or shorten the horizon", "limit") from None
    if not computed.shield_exists and needed:
        raise ExperimentError("no safe strategy exists from the start: the shielded combinations cannot run",
                              states=computed.graph.n_states)
    onward = shields.SafeOnward(computed, horizon_samples, forget_every=table.forget_every)
    return (table if computed.shield_exists else None), time.perf_counter() - t0, computed.graph.n_states, onward


def _lower(first: str, fewer_runs: str | None) -> str:
    """The advice of a budget refusal: lower ``first``, or ``fewer_runs`` (:func:`run_experiment`)."""
    return f"lower {first}" + (f", {fewer_runs}" if fewer_runs else "")


def run_experiment(result: CompileResult, *, seeds: Sequence[int] = (1, 2, 3, 4, 5), episodes: int = 500,
                   evaluation_runs: int = 100, reward_function: str | None = None, horizon_samples: int | None = None,
                   parallel: int = 16, max_states: int = 5_000_000, combinations: Sequence[str] | None = None,
                   bins: Sequence[float] | None = None, counterfactuals: bool = True, replay: int = 1,
                   growth: float | None = GROWTH, ablation: bool = False, observe_time: bool = True,
                   max_bytes: int | None = None, memo: bool = True,
                   progress: Callable[[str], None] | None = None,
                   fewer_runs: str | None = "the seeds or the combinations",
                   explore_progress: Callable[[int, int, int], None] | None = None,
                   explore: str = "uniform") -> Report:
    """Run every combination for every seed; a JSON-ready report (see :func:`render_markdown`).
    ``bins``: the widths of the continuous observations (default: derived from the model and its
    goal, :func:`rac.learning.strategy.derived_bins`); ``counterfactuals``: the RA combinations learn
    from counterfactual experiences (:mod:`rac.learning.counterfactual`); ``replay``: backward
    replays per batch; ``growth``: batches grow with the episodes learned (:func:`rac.learning.qlearning.learning`),
    so the greedy strategy is evaluated after 1, 2, 3, ... episodes at first; ``ablation``: also
    SS&RA without each of these (:data:`ABLATION`), in ``report["ablation"]``; ``observe_time``: the
    decision time is added to the discrete observations (:func:`_with_time`); ``max_bytes``: the
    memory budget of the shield and the learning (None: none), checked before either starts
    (:func:`rac.engine.budget.learning_bytes` for all runs together); ``memo``: the episodes recall
    the steps taken before (:class:`rac.learning.episodes.EpisodeBatch`'s ``memo``; the same results,
    benchmarks/learning.py compares the time); ``fewer_runs``: what else the caller's user may lower to run
    fewer runs, as the budget's refusals advise it (``rac sweep`` has no option for the combinations; None:
    nothing else); ``explore_progress``: the shield's exploration, layer by layer (``(sample, frontier,
    states so far)``, as :func:`rac.engine.explore.explore`'s ``progress``; the CLI's bar counts it). Every combination
    learns with :data:`LEARNER` and learns to the budget (the greedy strategy kept is the best
    evaluated: its return keeps improving late, after 90 to 490 of 500 episodes on examples/paper).

    All runs learn together in one batch of episodes (:func:`rac.learning.lockstep.run_together`),
    then all evaluations run together: each result is the one the run has alone, and a run's
    learning time is its own computation plus its share of the batch's steps."""
    # stormpy (via rac.learning.lockstep): importing rac.studies.experiment stays light
    from rac.learning.lockstep import Interrupted, Job, run_together

    # stormpy (via rac.learning.qlearning): importing rac.studies.experiment stays light
    from rac.learning.qlearning import LearningResult, learning

    # stormpy (via rac.learning.runs): importing rac.studies.experiment stays light
    from rac.learning.runs import evaluation_steps

    # stormpy (via rac.learning.strategy): importing rac.studies.experiment stays light
    from rac.learning.strategy import derived_bins

    automaton = result.raise_for_errors()
    if automaton.model is None or result.model_data is None:
        raise ExperimentError("the file has no `model` block: learning needs the scenario model")
    horizon = horizon_samples if horizon_samples is not None else automaton.steps
    text = reward_function if reward_function is not None else PAPER_REWARD_FUNCTION
    if reward_function is None:
        problem = default_reward_problem(i.name for i in automaton.inputs)
        if problem is not None:
            raise ExperimentError(problem, "usage")
    try:
        rf = parse_expr(text)
    except ValueError as exc:
        raise ExperimentError(f"--reward-function: {exc}", "usage") from None
    if explore not in EXPLORE:
        raise ExperimentError(f"--explore: one of {', '.join(EXPLORE)}, not {explore!r}", "usage")
    if EXPLORE[explore] is not None and result.model_data is not None and result.model_data.goal_anywhere:
        raise ExperimentError(f"--explore {explore}: the goal has no position (a goal of time alone), so "
                              "`dist_goal()` reads 0 everywhere and there is nothing to head for; explore "
                              "uniformly (the default)", "usage")
    wanted = [c for c in COMBINATIONS if combinations is None or c[0] in combinations]
    discrete, continuous, source_query = _learning_spec(result)
    if ablation or (counterfactuals and any(kind == "automaton" for _, _, kind in wanted)):
        _check_counterfactual_observation(result, ablation)
    derived = derived_bins(result.model_data, [parse_expr(text) for text in continuous])
    widths = tuple(float(b) for b in bins) if bins is not None else derived
    if bins is not None and (len(widths) != len(continuous) or not all(w > 0 and math.isfinite(w) for w in widths)):
        raise ExperimentError(f"--bins: {len(continuous)} positive widths, one per continuous observation "
                              f"({', '.join(continuous)}), not {','.join(f'{w:g}' for w in widths)}", "usage")
    bins_from = "--bins" if bins is not None else "derived from the model's action grid and goal"
    shared = EpisodeBatch(result, reward="automaton", horizon_samples=horizon,  # its onward: the shield's, below
                          counterfactuals=counterfactuals or ablation, memo=memo)
    try:  # checked before the shield and the learning, which would meet it only after them
        objective = shared.expression(rf) if any(kind == "function" for _, _, kind in wanted) else None
    except CheckError as exc:
        raise ExperimentError(f"--reward-function: `{text}`: {exc.brief()}", "usage") from None
    count = (len(wanted) + (len(ABLATION) if ablation else 0)) * len(seeds)
    needed = learning_bytes(episodes=episodes, parallel=parallel, steps=shared.max_steps, runs=count,
                            observations=len(discrete) + len(continuous) + int(observe_time), actions=shared.n_actions)
    try:  # before the shield and the learning: the runs learn together, so their tables add up
        check_estimate(f"learning {counted(count, 'run')} together", needed, max_bytes,
                       _lower(f"the episodes per run ({episodes:,}, --episodes)", fewer_runs))
        # and every strategy's evaluation runs together afterwards: it met the budget only as a MemoryError
        check_estimate(f"evaluating {counted(count, 'strategy', 'strategies')} over "
                       f"{counted(evaluation_runs, 'run')} each together",
                       evaluation_bytes(runs=count * evaluation_runs, steps=shared.max_steps, samples=horizon),
                       max_bytes, _lower(f"the evaluation runs ({evaluation_runs:,}, --runs)", fewer_runs))
    except BudgetExceeded as exc:
        raise ExperimentError(str(exc), "limit") from None
    # The shield also judges every combination's runs: a run is safe at the goal only if it can stay
    # safe from there to the horizon, the horizon the shield guarantees.
    if progress:
        progress("computing the safety shield")
    shield_table, shield_seconds, shield_states, onward = _shield(
        result, horizon, max_states, any(shielded for _, shielded, _ in wanted), max_bytes, explore_progress)
    shared.onward = onward
    # the ablation learns SS&RA: its rows are measured against SS&RA's optimum, also when the table leaves
    # SS&RA out (--combination)
    solved = [*wanted, *(c for c in COMBINATIONS if c[0] == "SS&RA" and ablation and c not in wanted)]
    optima = _optima(result, solved, shield_table, horizon, onward, rf, max_states, progress, EXPLORE[explore])
    # (label, seed, shield, reward kind, options): counterfactuals for the automaton's rewards only
    # (the reward function knows nothing of the automaton: the paper's RF learner)
    main = Options(widths, counterfactuals, replay, time=observe_time)
    runs = [(label, seed, shield_table if shielded else None, kind,
             main if kind == "automaton" else dataclasses.replace(main, counterfactuals=False))
            for label, shielded, kind in wanted for seed in seeds]
    variants = _ablation(main, widths if bins is not None else default_widths(continuous)) if ablation else []
    if variants and shield_table is None:
        raise ExperimentError("the ablation learns SS&RA: it needs the safety shield")
    runs += [(f"ablation {i}", seed, shield_table, "automaton", options)
             for i, options in enumerate(variants) for seed in seeds]
    what = (f"learning {counted(len(runs), 'run')} together ({', '.join(label for label, _, _ in wanted)}; "
            f"seeds {', '.join(map(str, seeds))})")
    if progress:
        progress(what)
    done = [0] * len(runs)
    shown = [0]

    def learned_so_far(run: int) -> Callable[[int, int, float], None]:
        """Each run's learning progress; the episodes of all runs announced at every tenth of the budget."""
        def report(episodes_done: int, budget: int, mean_return: float) -> None:
            done[run] = episodes_done
            tenth = 10 * sum(done) // (len(runs) * episodes)
            if progress and tenth > shown[0]:
                shown[0] = tenth
                progress(f"{what}: {sum(done):,} of {len(runs) * episodes:,} episodes")
        return report

    stopped: str | None = None  # where Ctrl-C stopped the runs: "learning", "evaluation" or nowhere
    try:  # a reward that is not a number, met while learning: the user's reward, not a bug
        learned = run_together([Job(learning(shared, discrete=_with_time(discrete) if options.time else discrete,
                                             continuous=continuous, shield=table, episodes=episodes,
                                             parallel=parallel, seed=seed, bins=options.bins,
                                             counterfactuals=options.counterfactuals, replay=options.replay,
                                             growth=growth, progress=learned_so_far(run),
                                             stop_after=-(-episodes // parallel) + 1, steer=EXPLORE[explore],
                                             **({**LEARNER, "replay_best": options.replay_best} if options.pessimistic
                                                else EARLIER)),
                                    None if kind == "automaton" else objective)
                                for run, (_, seed, table, kind, options) in enumerate(runs)], shared,
                               interruptible=True)
    except Interrupted as stop:  # each run's best evaluated strategy; none before its first evaluation
        learned, stopped = stop.results, "learning"
        if all(outcome is None for outcome, _ in learned):
            raise KeyboardInterrupt from None
    except RacValueError as exc:
        raise ExperimentError(f"learning stopped: {exc} (the reward function `{text}` or the automaton's "
                              "objective)") from None
    kept = [i for i, (outcome, _) in enumerate(learned) if outcome is not None]
    runs, learned = [runs[i] for i in kept], [learned[i] for i in kept]
    outcomes: list[LearningResult] = [outcome for outcome, _ in learned]
    evaluations: list[tuple[Any, float]] = [(None, 0.0)] * len(runs)
    if stopped is None:
        if progress:
            progress(f"evaluating {counted(len(runs), 'strategy', 'strategies')} over "
                     f"{counted(evaluation_runs, 'run')} each")
        try:
            evaluations = run_together([Job(evaluation_steps(outcome.strategy, runs=evaluation_runs, shield=table,
                                                             seed=seed, epsilon=EVALUATION_NOISE))
                                        for outcome, (_, seed, table, _, _) in zip(outcomes, runs)], shared,
                                       interruptible=True)
        except Interrupted as stop:  # the strategies stand, and the evaluations finished
            evaluations, stopped = stop.results, "evaluation"
    records: list[RunRecord] = []
    for (label, seed, _, _, options), (outcome, seconds), (evaluation, _) in zip(runs, learned, evaluations):
        history = outcome.history
        succeeded = (np.asarray(history.reached) & ~np.asarray(history.collided) & ~np.asarray(history.offroad)
                     & ~np.asarray(history.stranded))
        records.append(RunRecord(label, seed, seconds, outcome.episodes, outcome.first_success_episode,
                                 outcome.collisions_during_learning, outcome.offroad_during_learning,
                                 bool(outcome.greedy.success[0]),
                                 0 if evaluation is None else evaluation.successes,
                                 0 if evaluation is None else evaluation.runs,
                                 np.asarray(history.returns, dtype=float), succeeded,
                                 float(outcome.greedy.returns[0]),
                                 _value(optima.get("SS&RA" if label.startswith("ablation ") else label)),
                                 options.counterfactuals))
    ablation_records = [r for r in records if r.combination.startswith("ablation ")]
    records = [r for r in records if not r.combination.startswith("ablation ")]
    return {"file": automaton.model.scenario_path, "horizon_samples": horizon, "episodes": episodes,
            "seeds": list(seeds), "reward_function": text, "shield_seconds": shield_seconds,
            "shield_states": shield_states, "records": records, "bins": list(widths), "bins_from": bins_from,
            "derived_bins": list(derived), "replay": replay, "counterfactuals": counterfactuals, "growth": growth,
            "parallel": parallel, "optima": optima,
            "model_steps": {"recalled": shared.steps_recalled, "computed": shared.steps_computed,
                            "ahead": shared.steps_ahead},
            "explore": explore,
            "interrupted": stopped, "evaluation_runs": evaluation_runs,
            "observation": {"discrete": _with_time(discrete) if observe_time else discrete, "continuous": continuous,
                            "query": source_query},
            "learner": {key: list(v) if isinstance(v, tuple) else v for key, v in LEARNER.items()},
            "ablation": [{"bins": list(options.bins), "counterfactuals": options.counterfactuals,
                          "replay": options.replay, "time": options.time, "pessimistic": options.pessimistic,
                          "replay_best": options.replay_best and options.pessimistic,
                          "records": [r for r in ablation_records if r.combination == f"ablation {i}"]}
                         for i, options in enumerate(variants)]}


@dataclass(frozen=True)
class Options:
    """How one run learns: the observation's bin widths, counterfactual experiences, backward replays,
    the decision time observed (:func:`_with_time`), and :data:`LEARNER` (``pessimistic``) or
    :data:`EARLIER`."""

    bins: tuple[float, ...]
    counterfactuals: bool
    replay: int
    time: bool = True
    pessimistic: bool = True
    #: :data:`LEARNER`'s ``replay_best`` (the best learning episode seen replayed after every batch).
    replay_best: bool = True


def default_widths(continuous: Sequence[str]) -> tuple[float, ...]:
    """The fixed default widths of the observations (1 m, 0.5 m/s, 0.1 rad ...;
    :func:`rac.learning.strategy.default_bin`)."""
    # stormpy (via rac.learning.strategy): importing rac.studies.experiment stays light
    from rac.learning.strategy import default_bin

    return tuple(default_bin(parse_expr(text)) for text in continuous)


def _ablation(main: Options, other_bins: tuple[float, ...]) -> list[Options]:
    """SS&RA's variants: the experiment's options, then each ingredient taken away or changed alone,
    then all of them (see :data:`ABLATION`)."""
    return [main, dataclasses.replace(main, bins=other_bins),
            dataclasses.replace(main, counterfactuals=not main.counterfactuals),
            dataclasses.replace(main, replay=0 if main.replay else 1),
            Options(other_bins, not main.counterfactuals, 0 if main.replay else 1, main.time),
            dataclasses.replace(main, time=not main.time), dataclasses.replace(main, pessimistic=False),
            dataclasses.replace(main, replay_best=not main.replay_best)]


def _value(optimum: Report | None) -> float | None:
    value = None if optimum is None else optimum.get("value")
    return float(value) if isinstance(value, float) else None


def _optima(result: CompileResult, wanted: Sequence[tuple[str, bool, str]], table: Any, horizon: int, onward: Any,
            rf: Any, max_states: int, progress: Callable[[str], None] | None,
            steer: str | None = None) -> dict[str, Report]:
    """The exact optimum of every shielded combination (:func:`rac.learning.optimum.solve`) on the episodes it
    learns on, by label: its value and how it was computed, or why it is out of reach; with ``steer``, also
    what exploring steered by it can expect (``steered_success``)."""
    # stormpy (via rac.learning.optimum): importing rac.studies.experiment stays light
    from rac.learning.optimum import solve

    optima: dict[str, Report] = {}
    # one batch for every combination: they search the same shielded graph, whose steps the memo
    # recalls for the second (its bytes are handed back when the batch is gone, before the learning)
    batch = EpisodeBatch(result, reward="automaton", horizon_samples=horizon, onward=onward)
    for label, shielded, kind in wanted:
        if not shielded or table is None:
            continue
        if progress:
            progress(f"the exact optimum of {label} under the shield")
        try:
            best = solve(batch, objective=None if kind == "automaton" else rf, shield=table, max_states=max_states,
                         steer=steer)
        except (MemoryError, ValueError) as exc:  # the budget (BudgetExceeded is a MemoryError), an unusable model
            optima[label] = {"out_of_reach": str(exc)}
            continue
        optima[label] = {"value": best.value, "states": best.states, "method": best.method,
                         "seconds": best.seconds, "reaches_goal_safely": bool(best.run.success[0]),
                         "uniform_success": best.uniform_success,
                         "actions": best.run.actions[0].tolist(),
                         **({} if best.steered_success is None else {"steered_success": best.steered_success})}
    return optima


def _mean_sd(values: Sequence[float]) -> str:
    """``mean ± sd`` over the seeds (whole numbers for counts; one seed: its value alone)."""
    if not values:
        return "—"
    mean = float(np.mean(values))
    whole = all(float(v).is_integer() for v in values)
    shown = f"{mean:.0f}" if whole or abs(mean) >= 100 else f"{mean:.3g}"
    if len(values) == 1:
        return shown
    sd = float(np.std(values, ddof=1))
    return f"{shown} ± {sd:.0f}" if whole or sd >= 100 else f"{shown} ± {sd:.2g}"


def summary(report: Report, records: Sequence[RunRecord] | None = None) -> list[Report]:
    """Per combination: mean and spread over the seeds (of ``records``, default the report's)."""
    records = report["records"] if records is None else records
    rows = []
    for label in dict.fromkeys(r.combination for r in records):
        runs = [r for r in records if r.combination == label]
        first = [r.first_success_episode for r in runs if r.first_success_episode is not None]
        rows.append({
            "combination": label, "seeds": len(runs),
            "seconds": [r.seconds for r in runs],
            "first_success": first, "never_succeeded": sum(r.first_success_episode is None for r in runs),
            "collisions": [r.collisions_during_learning for r in runs],
            "offroad": [r.offroad_during_learning for r in runs],
            "greedy_success": sum(r.greedy_success for r in runs),
            "evaluation": [r.evaluation_successes / r.evaluation_runs for r in runs if r.evaluation_runs],
            "episodes": [r.episodes for r in runs],
            "greedy_returns": [r.greedy_return for r in runs],
            "optimum": runs[0].optimum,
            "shortfall": [_shortfall(r) for r in runs if r.optimum is not None],
            "counterfactuals": any(r.counterfactuals for r in runs),
        })
    return rows


def _shortfall(record: RunRecord) -> float:
    """How far the greedy return falls short of the exact optimum, relative to ``|optimum|``."""
    # stormpy (via rac.learning.optimum): importing rac.studies.experiment stays light
    from rac.learning.optimum import shortfall

    assert record.optimum is not None
    return shortfall(record.greedy_return, record.optimum)


def goal_out_of_reach(report: Report) -> str | None:
    """Why no episode of the shielded combinations can succeed, when the exact optimum under the shield found that
    no run the shield allows reaches the goal safely within the horizon (its ``uniform_success`` is 0, exact over
    them all); None when some run can, or no optimum says (no shielded combination, one out of reach)."""
    labels = [label for label, optimum in report.get("optima", {}).items()
              if "uniform_success" in optimum and not optimum["uniform_success"] > 0]
    if not labels:
        return None
    return (f"no run the shield allows reaches the goal safely within the horizon ({report['horizon_samples']} "
            f"samples; exact, over all of them, the optimum of {' and '.join(labels)}): no episode of "
            f"{' or '.join(labels)} can succeed, whatever the learner (a longer horizon, or another goal or scenario, "
            "may bring the goal within reach)")


def render_markdown(report: Report) -> str:
    """The experiment as a markdown table (mean ± standard deviation over the seeds)."""
    rows = summary(report)
    lines = [
        "| combination | learning time (s) | episodes until the first safe goal | episodes learned | "
        "collisions during learning (episodes) | greedy strategy safe at the goal and to the horizon | "
        f"success over {counted(_evaluation_runs(report), 'run')} with {EVALUATION_NOISE:g} random actions | "
        "greedy return | exact optimum under the shield (shortfall) | counterfactual experiences |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for row in rows:
        n = row["seeds"]
        first = _mean_sd(row["first_success"])
        if row["never_succeeded"]:
            first += f" ({row['never_succeeded']} of {n} seeds never)"
        lines.append(
            f"| {row['combination']} | {_mean_sd(row['seconds'])} | {first} | {_mean_sd(row['episodes'])} | "
            f"{_mean_sd(row['collisions'])} | {row['greedy_success']} of {n} seeds | "
            f"{_mean_sd([100 * v for v in row['evaluation']]) + ' %' if row['evaluation'] else '—'} | "
            f"{_mean_sd(row['greedy_returns'])} | "
            f"{_optimum_cell(row)} | {'yes' if row['counterfactuals'] else 'no'} |")
    notes = [
        "",
        *_interrupted(report),
        *(f"Exact optimum of {label} under the shield: "
          + (f"out of reach ({optimum['out_of_reach']})" if "out_of_reach" in optimum else
             f"{optimum['value']:.1f} ({optimum['method']}, {optimum['seconds']:.2f} s)"
             + ("" if optimum.get("reaches_goal_safely", True) else ", a run that does not reach the goal safely")
             + _exploration(optimum))
          + "." for label, optimum in report.get("optima", {}).items()),
        f"Safety shield: {report['shield_states']:,} states, {report['shield_seconds']:.2f} s (computed once, "
        + _shield_use([row["combination"] for row in rows]) + ").",
        *_model_steps(report),
        f"Seeds {', '.join(map(str, report['seeds']))}; budget {report['episodes']} episodes per run; horizon "
        f"{report['horizon_samples']} samples; reward function `{report['reward_function']}`; observation "
        f"{{{', '.join(report['observation']['discrete'])}}}->{{{', '.join(report['observation']['continuous'])}}} "
        f"in bins of {_widths(report['bins'])} ({report['bins_from']}); {_observed_from(report)}",
        "Learning: tabular Q-learning"
        + (", alpha 1, untried actions never preferred to tried ones (the greedy strategy is the best run seen), "
           "the best episode seen replayed after each batch, epsilon 1 down to 0.2 over the budget, learning to "
           "the budget" if report.get("learner") else "")
        + f", {'backward replay of each batch' if report['replay'] else 'no replay'}"
        f"{' (' + str(report['replay']) + ' times)' if report['replay'] > 1 else ''}; batches of "
        + (f"ceil({report['growth']:g} x episodes learned) episodes, 1 to {report['parallel']}, the greedy strategy "
           "evaluated after each (after 1, 2, 3, 4, 5, 7, 9, 12, 15 ... episodes)" if report['growth']
           else f"{report['parallel']} episodes, the greedy strategy evaluated after each")
        + "; counterfactual experiences (every transition replayed from every automaton location) for the "
        "reward automaton's combinations" + ("" if report['counterfactuals'] else ": off") + "; "
        + _explored(report) + ".",
        "Values are mean ± standard deviation over the seeds; 'episodes until the first safe goal' counts only "
        "the seeds that got there.",
        f"A run succeeds when it reaches the goal without colliding or leaving the road and, from the state it "
        f"reaches the goal in, some run stays safe to the horizon ({report['horizon_samples']} samples, the "
        "shield's): a run that reaches the goal only to leave the road after it does not count.",
    ]
    return "\n".join(lines + notes)


def _explored(report: Report) -> str:
    """How the learning episodes explored (``--explore``; reports written before it explored uniformly)."""
    steer = EXPLORE.get(report.get("explore", "uniform"))
    if steer is None:
        return "exploring choices uniform among the allowed actions"
    return (f"exploring choices (--explore {report['explore']}) half towards the goal, the allowed action whose "
            f"`{steer}` one decision later is least (looked up in the model, every combination alike), half "
            "uniform among the allowed actions")


def _shield_use(labels: Sequence[str]) -> str:
    """Whom the shield served: the shielded combinations in the table, and in any case the judge of a run's
    safety after the goal (the note said "used by SS&RA and SS&RF" under a table of RA or RF alone)."""
    shielded = [label for label, is_shielded, _ in COMBINATIONS if is_shielded and label in labels]
    if not shielded:
        return "used only to judge whether a run can stay safe from the goal to the horizon"
    return f"used by {' and '.join(shielded)}"


def _interrupted(report: Report) -> list[str]:
    """What Ctrl-C left of the runs, when it stopped them."""
    stopped = report.get("interrupted")
    if not stopped:
        return []
    records: list[RunRecord] = report["records"] or [r for variant in report.get("ablation", [])
                                                      for r in variant["records"]]
    low, high = min((r.episodes for r in records), default=0), max((r.episodes for r in records), default=0)
    learned = f"{low:,}" if low == high else f"{low:,} to {high:,}"
    # "stopped_by": the signal that stopped the command (rac.cli.common.stopping_signal; absent: Ctrl-C)
    how = "Terminated (SIGTERM)" if report.get("stopped_by") == "SIGTERM" else "Interrupted (Ctrl-C)"
    if stopped == "evaluation":
        return [f"{how} while evaluating: every run learned its {report['episodes']:,} episodes; "
                "evaluations not finished are left out (a row of none shows '—')."]
    return [f"{how} while learning: each run shows the best strategy it had evaluated (the one it "
            f"keeps, as at the budget's end), after "
            f"{learned} of {report['episodes']:,} episodes learned; a run not evaluated yet is left out (the "
            "rows' seeds are those shown); no evaluation runs ('—')."]


def _model_steps(report: Report) -> list[str]:
    """How many episode-steps called the model and how many were recalled (reports written before
    the memo have neither)."""
    steps = report.get("model_steps")
    if not steps:
        return []
    total = steps["recalled"] + steps["computed"]
    if not total:
        return []
    ahead = steps.get("ahead", 0)
    return [f"Model: {total:,} episode-steps (learning and evaluation), {100 * steps['recalled'] / total:.0f} % "
            "recalled from an earlier episode's same step (the same state and action: the model is deterministic), "
            "the rest computed" + (f"; and {ahead:,} to look one decision ahead for the exploring choices "
                                   "(--explore)" if ahead else "") + "."]


def _exploration(optimum: Report) -> str:
    """What exploring uniformly under the shield can expect (reports written before it have none)."""
    # stormpy (via rac.learning.optimum): importing rac.studies.experiment stays light
    from rac.learning.optimum import exploration_text

    if "uniform_success" not in optimum:
        return ""
    if not optimum["uniform_success"] > 0:  # exact over the complete graph: no allowed run reaches the goal
        return ("; under the shield " + exploration_text(optimum["uniform_success"])
                + ", nor does any run the shield allows (exact, over all of them within the horizon): no episode "
                "can succeed, whatever the learner")
    text = ("; under the shield " + exploration_text(optimum["uniform_success"])
            + ", what a learner exploring at epsilon near 1 can expect before it has learned anything")
    steered = optimum.get("steered_success")
    if steered is not None:  # --explore goal: what its exploring episodes can expect, exact over the same graph
        text += ("; an episode exploring as --explore does reaches it safely with probability "
                 + (f"{100 * steered:.3g} % (exact; {1 / steered:.3g} episodes on average until the first)"
                    if steered > 0 else "0"))
    return text


def _optimum_cell(row: Report) -> str:
    """The optimum and the seeds' shortfall from it in percent (— without an optimum)."""
    if row["optimum"] is None:
        return "—"
    within = sum(v <= 0.05 for v in row["shortfall"])
    return (f"{row['optimum']:.1f} ({_mean_sd([100 * v for v in row['shortfall']])} % below; "
            f"{within} of {len(row['shortfall'])} within 5 %)")


def _widths(widths: Sequence[float]) -> str:
    return ", ".join(f"{w:g}" for w in widths)


def render_ablation(report: Report) -> str:
    """The ablation (SS&RA with each ingredient switched, :data:`ABLATION`) as a markdown table."""
    lines = ["| SS&RA | bins | counterfactual experiences | backward replay | time observed | untried actions | "
             "best episode replayed | episodes until the first safe goal | episodes learned | greedy strategy safe "
             "at the goal | greedy run's return | within 5 % of the optimum |",
             "| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |"]
    for name, variant in zip(ABLATION, report.get("ablation", [])):
        rows = summary(report, variant["records"])
        if not rows:
            continue
        row = rows[0]
        first = _mean_sd(row["first_success"])
        if row["never_succeeded"]:
            first += f" ({row['never_succeeded']} of {row['seeds']} seeds never)"
        close = sum(v <= 0.05 for v in row["shortfall"])
        within = "—" if row["optimum"] is None else f"{close} of {row['seeds']} seeds"
        lines.append(f"| {name} | {_widths(variant['bins'])} | {'on' if variant['counterfactuals'] else 'off'} | "
                     f"{'on' if variant['replay'] else 'off'} | {'yes' if variant.get('time', True) else 'no'} | "
                     f"{'never preferred' if variant.get('pessimistic', True) else 'at 0'} | "
                     f"{'yes' if variant.get('replay_best', True) else 'no'} | {first} | "
                     f"{_mean_sd(row['episodes'])} | {row['greedy_success']} of {row['seeds']} seeds | "
                     f"{_mean_sd(row['greedy_returns'])} | {within} |")
    return "\n".join(lines + ["", f"Seeds {', '.join(map(str, report['seeds']))}; budget {report['episodes']} "
                               "episodes per run; every row learned (not copied from the table above)."])


def _evaluation_runs(report: Report) -> int:
    """The evaluation runs asked for (reports written before it was kept: those of the first run)."""
    if "evaluation_runs" in report:
        return int(report["evaluation_runs"])
    records: list[RunRecord] = report["records"]
    return records[0].evaluation_runs if records else 0


def write_outputs(report: Report, out_dir: Path) -> list[Path]:
    """``experiment.md``, ``results.json``, ``returns.png`` and ``first_success.png`` in ``out_dir``."""
    # matplotlib (via rac.output.plots): importing rac.studies.experiment stays light
    from rac.output.plots import plot_first_success, plot_learning_curves

    out_dir.mkdir(parents=True, exist_ok=True)
    names = ("experiment.md", *(("ablation.md",) if report.get("ablation") else ()), "results.json", "returns.png",
             "first_success.png")
    for name in names:  # before any is written: a folder in the way of the last left the first ones replaced
        if (out_dir / name).is_dir():
            raise IsADirectoryError(errno.EISDIR, os.strerror(errno.EISDIR), str(out_dir / name))
    records: list[RunRecord] = report["records"]
    texts = [(out_dir / "experiment.md", render_markdown(report) + "\n")]
    if report.get("ablation"):
        texts.append((out_dir / "ablation.md", render_ablation(report) + "\n"))
    texts.append((out_dir / "results.json", results_json(report)))

    def curves(field: str) -> dict[str, np.ndarray]:
        out = {}
        for label in dict.fromkeys(r.combination for r in records):
            rows = [getattr(r, field).astype(float) for r in records if r.combination == label]
            width = max(len(row) for row in rows)
            out[label] = np.array([np.pad(row, (0, width - len(row)), constant_values=np.nan) for row in rows])
        return out

    def plots() -> list[Path]:
        firsts: dict[str, list[int | None]] = {}
        for r in records:
            firsts.setdefault(r.combination, []).append(r.first_success_episode)
        return [plot_learning_curves(curves("returns"), out_dir / "returns.png", ylabel="episode return",
                                     title="learning curves", smooth=10, panels=True),
                plot_first_success(firsts, int(report["episodes"]), out_dir / "first_success.png")]

    def nested(k: int) -> list[Path]:
        # each text's temporary file stays open while the rest (the plots last: seconds) are made; the renames
        # come together at the end, so Ctrl-C or an error before leaves the previous run's files as they were,
        # never a new table beside the plots of another run
        if k == len(texts):
            return plots()
        path, text = texts[k]
        inner: list[Path] = []

        def write(handle: IO[bytes]) -> None:
            handle.write(text.encode("utf-8"))
            inner.extend(nested(k + 1))

        return [atomic_write(path, write), *inner]

    return nested(0)


def results_json(report: Report) -> str:
    """``results.json``'s text: the report with every run's record (what ``rac experiment --format json`` prints)."""

    def as_json(r: RunRecord) -> Report:
        return {"combination": r.combination, "seed": r.seed, "seconds": r.seconds, "episodes": r.episodes,
                "first_success_episode": r.first_success_episode,
                "collisions_during_learning": r.collisions_during_learning,
                "offroad_during_learning": r.offroad_during_learning, "greedy_success": r.greedy_success,
                "greedy_return": round(r.greedy_return, 4), "counterfactuals": r.counterfactuals,
                "optimum": r.optimum, "shortfall": None if r.optimum is None else _shortfall(r),
                "evaluation_successes": r.evaluation_successes, "evaluation_runs": r.evaluation_runs,
                "returns": [round(float(v), 4) for v in r.returns],
                "succeeded": [bool(v) for v in r.succeeded]}

    data = {key: value for key, value in report.items() if key not in ("records", "ablation")}
    data["runs"] = [as_json(r) for r in report["records"]]
    data["ablation"] = [dict(variant, name=name, records=[as_json(r) for r in variant["records"]])
                        for name, variant in zip(ABLATION, report.get("ablation", []))]
    # every string as rac shows it: a file name's undecodable byte is no lone surrogate, which strict JSON
    # readers refuse
    return json_text(data, indent=1) + "\n"
