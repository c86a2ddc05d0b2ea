"""Episodes of the scenario model with a reward automaton's reward, stepped together (issue 5).

:class:`EpisodeBatch` runs ``n`` episodes of the vehicle model of a ``.ra`` file's ``model`` block
at once with numpy, one *step* per decision period (``decide_every`` samples), for learning
(:mod:`rac.learning.qlearning`, :class:`rac.learning.gym.ScenarioEnv`). An episode starts at the ego's start
(sample 0, jerk and turn 0, the automaton in its initial location, every reward 0).

**One step** applies each episode's chosen (jerk, turn) pair (a row of :attr:`EpisodeBatch.action_pairs`)
and takes up to ``decide_every`` samples. **One sample** ``k -> k + 1`` is the product semantics of
:mod:`rac.engine.product`, on floats as :mod:`rac.runtime.interpreter` computes them:

1. the ego moves: the state at ``k + 1`` is ``sense()`` of the state at ``k`` with the chosen pair
   (:meth:`rac.model.batch.BatchModel.sense`, as :mod:`rac.engine.simulate` advances runs);
2. every input is read from its binding on sample ``k + 1`` with :class:`rac.engine.evaluate.Evaluator`:
   booleans as they are, numbers as the emitted model's significand ``d2i(e)`` (truncated towards
   zero) over the scale; ``prev(e)`` is ``e`` at sample ``k`` (at the first sample, ``e`` in the
   initial state). A number outside the input's declared bounds is *clipped* to them (the runtime
   would raise), an ``int`` input's value truncated to a whole number; every value changed so is
   counted in :attr:`EpisodeBatch.clipped` (per input in :attr:`EpisodeBatch.clipped_inputs`);
3. the automaton takes the sample with those inputs (:class:`rac.runtime.batch.BatchRewardAutomaton`:
   accrue with the held inputs, then the edge), which gives the sample's reward: the objective's
   increase (``reward="automaton"``), or the value of a plain reward expression over the model's
   vocabulary and the inputs on the sample (its text, or a checked expression; booleans count 0/1), e.g. the
   paper's Eq. 9 ``10*!isClose + (5 + 100*goal())*prog + comf``;
4. the episode *terminates* when the ``goal`` expression (default ``goal()``) holds on the sample
   (after the edge, so it may read the location and rewards), and is *truncated* when the sample
   is the horizon's last one without the goal. Either way the automaton's ``at end`` clauses apply
   with the sample's inputs, and in automaton mode their increase is added to the reward. The goal
   is checked from sample 1 on: an episode never ends before its first step. With ``episode ends
   when COND`` in the automaton, the episode also *ends* (:attr:`StepResult.ended`) at the sample
   whose inputs satisfy COND: the automaton applied its ``at end`` clauses in step 3 (their increase
   is in the sample's reward), exactly where the emitted model's run ends (:mod:`rac.engine.product`).

A step's reward is the sum of its samples' rewards (in sample order). A collision or leaving the
road does *not* end an episode (UPPAAL's semantics: the run goes on); :class:`StepResult` flags it
for the learner to count. Episodes that are done stay frozen (their state is kept, their reward is
0) until the next :meth:`EpisodeBatch.reset`, which restarts all ``n``, or
:meth:`EpisodeBatch.reset_rows`, which restarts some of them.

The inputs must satisfy the automaton's ``assume`` (the runtime refuses other valuations):
:class:`ValueError` when the bindings' values break it. :class:`rac.model.ModelRangeError` when a
sensed value or a numeric binding's significand leaves int32 (the emitted model aborts there).

Example::

    result = compile_file("examples/left_turn/model.ra")
    episodes = EpisodeBatch(result, horizon_samples=30)
    episodes.reset(64)
    while not episodes.done.all():
        out = episodes.step(rng.integers(episodes.n_actions, size=episodes.n))
        returns += out.reward
"""

from __future__ import annotations

import copy
import dataclasses
import numbers
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from rac import ir
from rac.check.queries import lower_expression
from rac.compiler import CompileResult
from rac.core.caller import require_bool
from rac.core.diagnostics import RacError, RacValueError
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.bindings import Bindings
from rac.engine.budget import EPISODE_MEMOS
from rac.engine.compiled import compile_expressions
from rac.engine.evaluate import Evaluator, Frame
from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.parser import parse_expression
from rac.learning.counterfactual import Counterfactuals, Replayer, Sample
from rac.model.data import ModelData
from rac.model.program import CheckedProgram
from rac.model.sample import ACTION, collides
from rac.runtime.batch import BatchRewardAutomaton
from rac.runtime.semantics import InputSpec, clip_column, input_specs

__all__ = ["GOAL", "EpisodeBatch", "Expression", "StepResult", "parse_expr"]

#: The default goal: the model's ``goal()`` (the planning problem's goal region and time interval).
GOAL: ie.Expr = ie.call("goal")
#: The model functions of a state alone (its ego and sample, not the run's history like ``collide()``
#: under ``collision sticky``): computed on a sample, they are handed on to the next sample's ``prev``.
_OF_THE_STATE = ("mindist", "offroad", "goal", "dist_goal")
#: A step's computed samples are taken together (:meth:`EpisodeBatch._together`) while they are at most
#: this many rows (samples times episodes): beyond, one sample's rows are enough to amortise numpy's
#: calls, and all of them together would hold large temporaries.
_TOGETHER_ROWS = 1 << 17

#: An expression as the engine's entry points take it: text, a parsed node (both checked against
#: the batch's automaton, :func:`rac.check.queries.lower_expression`) or a checked expression.
Expression = str | ast.Expr | ie.Expr


def parse_expr(text: str) -> ast.Expr:
    """One expression of the query language, parsed, not checked (:func:`rac.lang.parser.parse_expression`);
    :class:`ValueError` when the text is not one expression. The engine checks it against the
    automaton when it is handed to it (:meth:`EpisodeBatch.expression`)."""
    return parse_expression(text)


@dataclass(frozen=True)
class StepResult:
    """What one :meth:`EpisodeBatch.step` did, per episode (arrays of shape ``(n,)``)."""

    #: float64: the step's reward (0 for episodes already done before this step).
    reward: np.ndarray
    #: bool: the goal was reached in this step.
    terminated: np.ndarray
    #: bool: the horizon was reached in this step without the goal.
    truncated: np.ndarray
    #: bool: ``collide()`` held at some sample of this step.
    collided: np.ndarray
    #: bool: ``offroad()`` held at some sample of this step.
    offroad: np.ndarray
    #: bool: the goal was reached in this step in a state from which no run stays safe to the horizon
    #: (judged only with ``onward``; else always False).
    stranded: np.ndarray
    #: bool: the automaton's ``episode ends when`` held at a sample of this step: the episode ended
    #: there, its ``at end`` clauses applied (always False without the declaration). A gym
    #: environment reports ``terminated`` for it as for the goal.
    ended: np.ndarray


def _reads_location_or_rewards(expr: ie.Expr) -> bool:
    return any(r.kind in (ie.RefKind.REWARD, ie.RefKind.LOCATION, ie.RefKind.LOCATION_INDEX) for r in ie.refs(expr))


def _spread(state: _State, where: slice, rows: np.ndarray, location: np.ndarray, rewards: dict[str, np.ndarray],
            prev: Frame | None = None) -> Frame:
    """The frame of ``state``'s episodes ``where``, each repeated by ``rows`` (one per location), in
    the locations ``location`` with the reward values ``rewards``."""
    return Frame(k=state.k[where][rows], ego=state.ego[where][rows], location=location, rewards=rewards,
                 inputs={name: values[where][rows] for name, values in state.inputs.items()}, prev=prev,
                 crashed=state.crashed[where][rows])


class _Inputs:
    """Every input's value from its binding on a frame (see step 2 of the module docstring): the
    emitted model's reading (:class:`rac.engine.bindings.Bindings`), numbers clipped to their bounds."""

    def __init__(self, evaluator: Evaluator, automaton: ir.Automaton, compiled: bool) -> None:
        self.scale = evaluator.scale_d
        self.bindings = Bindings(evaluator, automaton, "an episode", compiled=compiled)
        #: Each input as it is clipped: an ``int`` input's bounds are the whole numbers within them.
        self.specs: list[InputSpec] = [
            dataclasses.replace(spec, low=float(np.ceil(spec.low)), high=float(np.floor(spec.high)))
            if spec.kind == "int" else spec for spec in input_specs(automaton)]

    def read(self, frame: Frame, clipped: dict[str, int] | None = None,
             changes: dict[str, np.ndarray] | None = None, *, shown: bool = False) -> dict[str, np.ndarray]:
        """Input name -> ``(n,)`` values (bool, or float64 reals); counts clipped values into ``clipped``
        and, with ``changes``, puts each numeric input's ``(n,)`` clipped-or-truncated mask there.
        ``shown``: only shown, never fed to the automaton (sample 0): a number beyond int32 is clipped like
        any other, not refused (the emitted model reads no binding there)."""
        out: dict[str, np.ndarray] = {}
        for spec, column in zip(self.specs, self.bindings.columns(frame, saturate=shown)):
            if spec.is_bool:
                out[spec.name] = column
                continue
            real = column / self.scale  # d2i() truncates towards zero, as the emitted model
            changed = np.zeros(real.shape, dtype=bool)
            if spec.kind == "int":
                whole = np.trunc(real)
                changed |= whole != real
                real = whole
            real, outside = clip_column(spec, real)  # the runtimes' bounds rule, not a copy of it
            changed |= outside
            if clipped is not None:
                clipped[spec.name] += int(changed.sum())
            if changes is not None:
                changes[spec.name] = changed
            out[spec.name] = real
        return out


@dataclass
class _State:
    """What a frame reads of every episode at one sample (full ``(n,)`` / ``(n, 7)`` arrays)."""

    k: np.ndarray
    ego: np.ndarray
    location: np.ndarray
    rewards: dict[str, np.ndarray]
    inputs: dict[str, np.ndarray]
    #: (n,) bool: ``collide()`` held at this sample or an earlier one (read under ``collision sticky``).
    crashed: np.ndarray

    def frame(self, rows: np.ndarray | slice, prev: Frame | None = None) -> Frame:
        return Frame(k=self.k[rows], ego=self.ego[rows], location=self.location[rows],
                     rewards={name: values[rows] for name, values in self.rewards.items()},
                     inputs={name: values[rows] for name, values in self.inputs.items()}, prev=prev,
                     crashed=self.crashed[rows])

    def copy(self) -> _State:
        return _State(self.k.copy(), self.ego.copy(), self.location.copy(),
                      {name: values.copy() for name, values in self.rewards.items()},
                      {name: values.copy() for name, values in self.inputs.items()}, self.crashed.copy())

    def take(self, rows: np.ndarray) -> _State:
        """A new state of the rows ``rows`` (indices, repeats allowed), in that order."""
        return _State(self.k[rows].copy(), self.ego[rows].copy(), self.location[rows].copy(),
                      {name: values[rows].copy() for name, values in self.rewards.items()},
                      {name: values[rows].copy() for name, values in self.inputs.items()}, self.crashed[rows].copy())

    def columns(self) -> list[np.ndarray]:
        """Everything but the rewards, one ``(n,)`` or ``(n, 7)`` array after the other."""
        return [self.k, self.ego, self.location, self.crashed, *(self.inputs[name] for name in sorted(self.inputs))]

    def put(self, where: np.ndarray, other: _State) -> None:
        """Copy ``other``'s rows where the ``(n,)`` mask ``where`` holds into this state (one masked copy
        per column: no gathered temporaries)."""
        np.copyto(self.k, other.k, where=where)
        np.copyto(self.ego, other.ego, where=where[:, None])
        np.copyto(self.crashed, other.crashed, where=where)
        np.copyto(self.location, other.location, where=where)
        for name, values in self.rewards.items():
            np.copyto(values, other.rewards[name], where=where)
        for name, values in self.inputs.items():
            np.copyto(values, other.inputs[name], where=where)


@dataclass
class _ModelSample:
    """The model's part of one sample for some episodes (``(m,)`` / ``(m, 7)`` arrays): the sensed
    state after it, the inputs read on it (and, per numeric input, which values were clipped or
    truncated), the labels, and — once known — the reward expression's value and the goal. ``frame``
    is the sample's frame when it was computed (None when it was recalled, :class:`_Transitions`)."""

    after: np.ndarray
    values: dict[str, np.ndarray]
    changes: dict[str, np.ndarray]
    collided: np.ndarray
    offroad: np.ndarray
    frame: Frame | None = None
    reward: np.ndarray | None = None
    reached: np.ndarray | None = None

    def late(self, values: list[np.ndarray], has_reward: bool, has_goal: bool) -> None:
        """Take the values of the reward expression (first, if ``has_reward``) and the goal (last, if ``has_goal``)."""
        m = self.after.shape[0]
        if has_reward:
            self.reward = np.broadcast_to(np.asarray(values[0], dtype=np.float64), (m,))
        goal = values[-1] if has_goal else np.zeros(m, dtype=bool)
        self.reached = np.broadcast_to(np.asarray(goal if goal.dtype == bool else goal != 0, dtype=bool), (m,))


@dataclass
class _Together:
    """The model's part of the next samples of some episodes (:meth:`EpisodeBatch._together`): ``(J, m)``
    arrays, sample ``j`` of episode ``i`` at ``[j, i]`` (``after`` ``(J, m, 7)``), and the model functions
    of the state computed on each sample (:data:`_OF_THE_STATE`, what :meth:`EpisodeBatch._carry` hands on)."""

    after: np.ndarray
    values: dict[str, np.ndarray]
    changes: dict[str, np.ndarray]
    collided: np.ndarray
    offroad: np.ndarray
    reached: np.ndarray
    reward: np.ndarray | None
    known: dict[str, np.ndarray]

    @property
    def samples(self) -> int:
        return int(self.after.shape[0])

    def sample(self, j: int, going: np.ndarray) -> _ModelSample:
        """Sample ``j`` of the episodes ``going`` (a mask over the ``m``): views when all of them go on."""
        every = bool(going.all())

        def pick(column: np.ndarray) -> np.ndarray:
            return column[j] if every else column[j][going]

        sampled = _ModelSample(pick(self.after), {name: pick(v) for name, v in self.values.items()},
                               {name: pick(v) for name, v in self.changes.items()}, pick(self.collided),
                               pick(self.offroad))
        sampled.reward = None if self.reward is None else pick(self.reward)
        sampled.reached = pick(self.reached)
        return sampled

    def functions(self, j: int, going: np.ndarray) -> dict[str, np.ndarray]:
        """The model functions of the state on sample ``j`` of the episodes ``going``."""
        return {name: values[j][going] for name, values in self.known.items()}


class _Transitions:
    """The model's part of every step taken so far, by the step's key: the sample, the sensed state,
    whether ``collide()`` held before and the chosen pair. The model is deterministic and that part
    of a sample reads nothing else (:meth:`EpisodeBatch.__init__` keeps this memo only when the
    bindings, the goal and the reward expression read no location, reward or held input), so a step
    taken again — episodes of one learner, and of learners sharing a batch, repeat most — recalls its
    samples instead of calling the model: the same values, bit for bit. A step is kept only when it
    ran to its model's end (the decision period, the goal or the horizon), and at most
    :data:`rac.engine.budget.EPISODE_MEMO_BYTES` are kept by all memos of the process together (then
    they stop growing; a memo hands its bytes back when its batch is gone)."""

    #: The bytes of one step's key in the index (the key, the slot, the dictionary's entry).
    INDEX_BYTES = 200

    def __init__(self, inputs: Sequence[InputSpec], has_reward: bool, samples: int) -> None:
        fields: list[tuple] = [("ego", np.int32, (7,)), ("collided", bool), ("offroad", bool), ("reached", bool)]
        if has_reward:
            fields.append(("reward", np.float64))
        self.inputs = [(f"v{i}", spec.name) for i, spec in enumerate(inputs)]
        self.numeric = [(f"c{i}", spec.name) for i, spec in enumerate(inputs) if not spec.is_bool]
        fields += [(field, bool if spec.is_bool else np.float64) for (field, _), spec in zip(self.inputs, inputs)]
        fields += [(field, bool) for field, _ in self.numeric]
        self.dtype = np.dtype(fields)
        self.has_reward = has_reward
        self.samples = samples
        self.index: dict[bytes, int] = {}
        self.store = np.zeros((0, samples), dtype=self.dtype)
        #: this memo's bytes within :data:`rac.engine.budget.EPISODE_MEMOS` (a gymnasium environment
        #: over a set of scenes has one batch per scene), handed back when the memo is collected
        self.share = EPISODE_MEMOS.share(self)

    @staticmethod
    def keys(k: np.ndarray, ego: np.ndarray, crashed: np.ndarray, pairs: np.ndarray) -> list[bytes]:
        """Each row's key (``k``, the sensed state, ``crashed``, the pair), as bytes."""
        table = np.empty((k.shape[0], 11), dtype=np.int32)
        table[:, 0] = k
        table[:, 1:8] = ego
        table[:, 8] = crashed
        table[:, 9:] = pairs
        raw = table.tobytes()
        return [raw[i:i + 44] for i in range(0, len(raw), 44)]

    def find(self, keys: list[bytes]) -> np.ndarray:
        """Each key's slot in the store, -1 for a step not kept."""
        index = self.index
        return np.fromiter((index.get(key, -1) for key in keys), dtype=np.int64, count=len(keys))

    def record(self, records: np.ndarray, rows: np.ndarray, j: int, sampled: _ModelSample) -> None:
        """Write ``sampled`` (with its goal known) into ``records[rows, j]``, field by field (in place)."""
        records["ego"][rows, j] = sampled.after
        records["collided"][rows, j] = sampled.collided
        records["offroad"][rows, j] = sampled.offroad
        records["reached"][rows, j] = sampled.reached
        if self.has_reward:
            records["reward"][rows, j] = sampled.reward
        for field, name in self.inputs:
            records[field][rows, j] = sampled.values[name]
        for field, name in self.numeric:
            records[field][rows, j] = sampled.changes[name]

    def taken(self, slots: np.ndarray) -> np.ndarray:
        """The samples of the steps in ``slots``, ``(m, samples)`` records: a copy (fancy indexing), so
        that a step's samples are gathered once, not once per sample (:meth:`recall` reads its columns)."""
        return self.store[slots]

    def recall(self, records: np.ndarray) -> _ModelSample:
        """One sample of some steps from its ``(m,)`` records (a column of :meth:`taken`'s, or rows of it)."""
        sampled = _ModelSample(records["ego"], {name: records[field] for field, name in self.inputs},
                               {name: records[field] for field, name in self.numeric},
                               records["collided"], records["offroad"])
        sampled.reward = records["reward"] if self.has_reward else None
        sampled.reached = records["reached"]
        return sampled

    def add(self, keys: list[bytes], records: np.ndarray) -> None:
        """Keep the steps ``keys`` with their samples' ``records`` ``(m, samples)``, as far as the
        bytes left of :data:`rac.engine.budget.EPISODE_MEMO_BYTES` allow."""
        fresh: dict[bytes, int] = {}  # episodes that took the same step: kept once
        for row, key in enumerate(keys):
            if key not in self.index:
                fresh.setdefault(key, row)
        if not fresh:
            return
        size, capacity = len(self.index), self.store.shape[0]
        row_bytes = self.dtype.itemsize * self.samples
        if size + len(fresh) > capacity:  # amortised doubling, within the bytes left
            left = EPISODE_MEMOS.left() - len(fresh) * self.INDEX_BYTES
            wanted = min(max(2 * capacity, size + len(fresh), 16), capacity + max(0, left) // row_bytes)
            if wanted > capacity:
                grown = np.zeros((wanted, self.samples), dtype=self.dtype)
                grown[:size] = self.store[:size]
                self.store = grown
                self.share.charge((wanted - capacity) * row_bytes)
        room = min(self.store.shape[0] - size,
                   max(0, EPISODE_MEMOS.left()) // self.INDEX_BYTES)
        chosen = list(fresh.items())[:room]
        if not chosen:
            return
        self.store[size:size + len(chosen)] = records[[row for _, row in chosen]]
        for offset, (key, _) in enumerate(chosen):
            self.index[key] = size + offset
        self.share.charge(len(chosen) * self.INDEX_BYTES)


def _merged(rows: np.ndarray, parts: Sequence[tuple[np.ndarray, _ModelSample]]) -> _ModelSample:
    """The samples of ``parts`` (each for some of ``rows``, together all of them) in ``rows``' order."""
    if len(parts) == 1:
        return parts[0][1]
    first = parts[0][1]
    m = rows.size

    def like(column: np.ndarray) -> np.ndarray:
        return np.empty((m, *column.shape[1:]), dtype=column.dtype)

    out = _ModelSample(like(first.after), {name: like(v) for name, v in first.values.items()},
                       {name: like(v) for name, v in first.changes.items()}, like(first.collided),
                       like(first.offroad), reward=None if first.reward is None else like(first.reward),
                       reached=None if first.reached is None else like(first.reached))
    for part_rows, part in parts:
        at = np.searchsorted(rows, part_rows)
        out.after[at] = part.after
        out.collided[at] = part.collided
        out.offroad[at] = part.offroad
        for name, values in part.values.items():
            out.values[name][at] = values
        for name, values in part.changes.items():
            out.changes[name][at] = values
        if out.reward is not None and part.reward is not None:
            out.reward[at] = part.reward
        if out.reached is not None and part.reached is not None:
            out.reached[at] = part.reached
    return out


class EpisodeBatch:
    """``n`` episodes of the scenario model with the automaton's reward, stepped together (one step =
    one decision period). See the module docstring for the semantics.

    Args:
        result: a checked file with a ``model`` block (:func:`rac.compiler.compile_file`), or its
            :class:`rac.model.program.CheckedProgram`.
        reward: ``"automaton"`` (the objective's increase, plus the ``at end`` bonus when the
            episode ends), or a reward expression evaluated on every sample (an :class:`rac.lang.ast.Expr`,
            or its text, parsed with :func:`parse_expr`).
        goal: the episode terminates at the first sample where this holds (default ``goal()``);
            None: episodes end at the horizon only.
        horizon_samples: the episode's length in samples (default the automaton's ``horizon``
            over its period).
        data: a variant of the model's data (default ``result.model_data``).
        compiled: read the bindings, the reward expression, the goal and observed expressions with
            compiled code (:mod:`rac.engine.compiled`, the default), or with the evaluator's walk
            (the reference: the same values, slower; benchmarks/learning.py compares them).
        memo: recall the model's part of a step taken before (:class:`_Transitions`; all batches of
            the process keep at most :data:`rac.engine.budget.EPISODE_MEMO_BYTES` together) instead
            of computing it again, where that part is a function of the step's state and pair (the
            default; the same values), and recall a step's replay from every location
            (:meth:`counterfactual`) replayed before (:class:`rac.learning.counterfactual.Replayer`'s
            memo). False: every step calls the model and replays.

    Attributes: ``n_actions``, ``action_pairs`` ``(P, 2)`` (jerk, turn significands; action ``a``
    is row ``a``), ``decide_every``, ``horizon_samples``, ``max_steps`` (steps in an episode that
    reaches the horizon), ``steps_recalled`` and ``steps_computed`` (episode-steps whose model part
    the memo recalled, and that called the model); after :meth:`reset`: ``n``, ``k`` ``(n,)`` the
    current sample, ``ego`` ``(n, 7)`` int32 the sensed significands, ``done`` ``(n,)`` terminated
    or truncated. ``clipped``: the number of binding values clipped to their input's bounds (or
    truncated to whole numbers for ``int`` inputs) since construction, over all episodes;
    ``clipped_inputs`` the same per input.
    """

    def __init__(self, result: CompileResult | CheckedProgram, *, reward: Expression = "automaton",
                 goal: Expression | None = GOAL, horizon_samples: int | None = None,
                 data: ModelData | None = None,
                 onward: Callable[[np.ndarray], np.ndarray] | None = None, counterfactuals: bool = False,
                 compiled: bool = True, memo: bool = True) -> None:
        automaton = result.automaton
        if automaton is None:
            raise RacValueError("the file has errors: there is no automaton to run")
        if automaton.model is None:
            raise RacValueError(f"`{automaton.name}` has no `model` block: episodes need the scenario model")
        data = data if data is not None else result.model_data
        if data is None:
            raise RacValueError("the model's data was not built (the scenario did not load): pass data=")
        self.result = result
        self.automaton = automaton
        self.data = data
        #: Whether a run can stay safe to the horizon from a state (``(m, 8)`` keys ``k, x, ..., turn``
        #: -> ``(m,)`` bool), e.g. :class:`rac.engine.shield.SafeOnward`: an episode that reaches the
        #: goal where it cannot is ``stranded`` (:class:`StepResult`). None: not judged.
        self.onward = onward
        for name, value in (("counterfactuals", counterfactuals), ("compiled", compiled), ("memo", memo)):
            require_bool(value, name)  # "no" was true
        self.evaluator = Evaluator(data, automaton)
        self.compiled = compiled
        self._bindings = _Inputs(self.evaluator, automaton, compiled)
        self.reward_expr: ie.Expr | None = None if reward == "automaton" else self.expression(reward)
        self.goal = None if goal is None else self.expression(goal)
        # what every sample reads after the automaton's edge: the reward expression and the goal, in one function
        self._after_edge = self._compile([expr for expr in (self.reward_expr, self.goal) if expr is not None])
        self._observers: dict[tuple, Callable[[Frame], list[np.ndarray]]] = {}
        if horizon_samples is not None and (isinstance(horizon_samples, bool)
                                            or not isinstance(horizon_samples, numbers.Integral)):
            # 1.5 was read as 1 sample, True as 1
            raise ValueError(f"horizon_samples must be a whole number of samples, not {horizon_samples!r}")
        horizon = automaton.steps if horizon_samples is None else int(horizon_samples)
        if horizon < 1:
            raise ValueError(f"horizon_samples must be at least 1, not {horizon}")
        self.horizon_samples = horizon
        self.decide_every = int(data.decide_every)
        self.max_steps = -(-horizon // self.decide_every)
        pairs = action_pairs(data)
        pairs.setflags(write=False)
        self.action_pairs = pairs
        self.n_actions = int(pairs.shape[0])
        self.guard = ActionGuard(data)
        self.clipped = 0
        self.clipped_inputs = {item.name: 0 for item in automaton.numeric_inputs}
        self._td = self.evaluator.model.native.td_d
        self._start = np.asarray(self.evaluator.model.native.initial_state(), dtype=np.int32)
        self._automata: BatchRewardAutomaton | None = None
        self.n = 0
        self.k = np.zeros(0, dtype=np.int64)
        self.ego = np.zeros((0, 7), dtype=np.int32)
        self.done = np.zeros(0, dtype=bool)
        self._now: _State | None = None
        self._prev: _State | None = None
        #: Record every step's samples, for :meth:`counterfactual` (off: a step records nothing).
        self.counterfactuals = counterfactuals
        self._replayer = Replayer(automaton, memo=memo)
        self._record: list[Sample] = []
        self._before: _State | None = None
        #: the last step's replay of every episode (:meth:`_replayed`), with the record and state it replays
        self._replay_kept: tuple[list[Sample], _State, Counterfactuals] | None = None
        self._last_reward = np.zeros(0)
        #: the rows of the last sample and the model functions computed on it (:data:`_OF_THE_STATE`):
        #: the next sample's prev(e) reads them instead of calling the model again
        self._carried: tuple[np.ndarray, dict[str, np.ndarray]] | None = None
        #: the model's part of the steps taken so far (None: every step calls the model)
        self._transitions = _Transitions(self._bindings.specs, self.reward_expr is not None, self.decide_every) \
            if memo and self._memoisable() else None
        #: Episode-steps whose model part was recalled from the memo, and computed (since construction).
        self.steps_recalled = 0
        self.steps_computed = 0
        #: Episode-steps :meth:`ahead` took to look one decision ahead (recalled or computed; since construction).
        self.steps_ahead = 0
        # Evaluate the expressions once on the start, so that a name the engine cannot read fails here.
        start = self._start_state(1)
        self._first = start  # one episode's start, read by reset_rows (never written)
        for expr in (self.reward_expr, self.goal):
            if expr is not None:
                self.evaluator.evaluate(expr, start.frame(slice(None)))

    def _memoisable(self) -> bool:
        """Whether a sample's model part is a function of its step's key (:class:`_Transitions`): the
        bindings read the model alone, the goal and the reward expression no location or reward, and
        no input of an earlier sample (which the key does not hold)."""
        bindings = [expr for _, _, expr in self._bindings.bindings.items]
        late = [expr for expr in (self.reward_expr, self.goal) if expr is not None]
        automaton = (ie.RefKind.REWARD, ie.RefKind.LOCATION, ie.RefKind.LOCATION_INDEX)
        return not (any(ie.reads_automaton(expr) or ie.reads_truth(expr) for expr in bindings)
                    or any(ie.reads_truth(expr) or any(r.kind in automaton for r in ie.refs(expr)) for expr in late)
                    or any(ie.reads_automaton(operand) for operand in ie.prev_operands(late)))

    def _compile(self, exprs: Sequence[ie.Expr]) -> Callable[[Frame], list[np.ndarray]]:
        """One function of a frame giving each expression's value (``Evaluator.evaluate``'s): compiled,
        or the evaluator's walk when the batch is not :attr:`compiled`."""
        if self.compiled:
            return compile_expressions(self.evaluator, exprs)
        evaluator = self.evaluator
        return lambda frame: [evaluator.evaluate(expr, frame) for expr in exprs]

    # ------------------------------------------------------------ state
    def _start_state(self, n: int) -> _State:
        k = np.zeros(n, dtype=np.int64)
        ego = np.tile(self._start, (n, 1))
        # The inputs shown at sample 0 (observe(), ScenarioEnv's info): the bindings on the start,
        # never fed to the automaton (it takes its first sample at k = 1) nor counted as clipped.
        crashed = np.zeros(n, dtype=bool)
        start = Frame(k, ego, crashed=crashed)
        crashed = collides(self.evaluator.function("mindist", start), self._td)  # collide() at the start
        # the same frame's mindist() (its cache is shared), with collide() so far
        inputs = self._bindings.read(dataclasses.replace(start, crashed=crashed), shown=True)
        location = np.full(n, self.automaton.initial, dtype=np.int64)
        rewards = {name: np.zeros(n) for name in self.automaton.rewards}
        self._carry(np.arange(n), start)
        return _State(k, ego, location, rewards, inputs, np.asarray(crashed, dtype=bool))

    def _carry(self, rows: np.ndarray, frame: Frame) -> None:
        """Keep ``frame``'s model functions of the state, the frame of episodes ``rows``."""
        known = frame.known()
        self._carried = (rows, {name: known[name] for name in _OF_THE_STATE if name in known})

    def reset(self, n: int) -> None:
        """Start ``n`` episodes at the ego's start (sample 0)."""
        if isinstance(n, bool) or int(n) != n or n < 1:
            raise ValueError(f"n must be a positive integer, not {n!r}")
        n = int(n)
        if self._automata is None or self._automata.n != n:
            self._automata = BatchRewardAutomaton(self.automaton, n)
        else:
            self._automata.reset()
        self.n = n
        self._before = None
        self._now = self._start_state(n)
        self._prev = self._now.copy()  # prev(e) at the start is e itself
        self.k = self._now.k
        self.ego = self._now.ego
        self.done = np.zeros(n, dtype=bool)

    def reset_rows(self, rows: np.ndarray | Sequence[int]) -> None:
        """Restart the episodes ``rows`` (indices into the batch) at the ego's start, as :meth:`reset`
        starts one; the other episodes go on untouched. The rows then sit at other samples than the
        rest, which :meth:`step` allows (every row keeps its own sample). For vector environments'
        autoreset (:mod:`rac.learning.vector`)."""
        now, prev, automata = self._require()
        where = np.unique(np.asarray(rows, dtype=np.int64).reshape(-1))
        if where.size and (where[0] < 0 or where[-1] >= self.n):
            raise ValueError(f"rows must be indices in [0, {self.n}), not {where.tolist()}")
        if where.size == 0:
            return
        self._carried = None  # the restarted rows' states changed
        mask = np.zeros(self.n, dtype=bool)
        mask[where] = True
        automata.reset(mask)
        self._sync(now, automata)
        start = self._first  # every episode starts from the same state: one row, broadcast
        for state in (now, prev):  # prev(e) at the start is e itself
            state.k[where] = start.k[0]
            state.ego[where] = start.ego[0]
            state.crashed[where] = start.crashed[0]
            state.location[where] = start.location[0]
            for name, values in state.rewards.items():
                values[where] = start.rewards[name][0]
            for name, values in state.inputs.items():
                values[where] = start.inputs[name][0]
        self.done[where] = False

    def select(self, rows: np.ndarray | Sequence[int]) -> None:
        """Keep the episodes ``rows`` (indices into the batch; an index may repeat), in that order, as
        the new batch of ``len(rows)`` episodes: each goes on exactly as its row would have. An
        exhaustive search branches every episode over its actions so (:mod:`rac.learning.optimum`)."""
        now, prev, automata = self._require()
        where = np.asarray(rows, dtype=np.int64).reshape(-1)
        if where.size == 0 or where.min() < 0 or where.max() >= self.n:
            raise ValueError(f"rows must be at least one index in [0, {self.n}), not {where.tolist()[:10]}")
        self._carried = None  # its rows are the old batch's
        self._automata = automata.take(where)
        self._now, self._prev = now.take(where), prev.take(where)
        self.n = int(where.size)
        self.k = self._now.k
        self.ego = self._now.ego
        self.done = self.done[where].copy()

    def memory(self, *, rewards: bool = False) -> np.ndarray:
        """``(n, m)`` float64: all that each episode's future depends on — the sample, the sensed
        state, the location, whether it collided, the inputs, the same of the previous sample (what
        ``prev(e)`` reads) and ``done`` — but not its rewards (with ``rewards``: those too). Two
        episodes with equal rows go on alike under the same actions; without the rewards, their
        rewards differ by what they hold now only when every update is a translation
        (:mod:`rac.learning.optimum` checks it)."""
        now, prev, _ = self._require()
        columns = [*now.columns(), *prev.columns(), self.done]
        if rewards:
            columns += [now.rewards[name] for name in sorted(now.rewards)]
        return np.column_stack([np.asarray(c, dtype=np.float64).reshape(self.n, -1) for c in columns]) + 0.0

    def _require(self) -> tuple[_State, _State, BatchRewardAutomaton]:
        if self._now is None or self._prev is None or self._automata is None:
            raise RuntimeError("no episodes yet: call reset(n) first")
        return self._now, self._prev, self._automata

    def state_keys(self, rows: slice | None = None) -> np.ndarray:
        """``(n, 8)`` int32 rows ``k, x, y, v, acc, head, jerk, turn``: the shield's state rows
        (:meth:`rac.engine.shield.ShieldTable.masks_for`); of the episodes ``rows`` only, if given."""
        now, _, _ = self._require()
        where = slice(None) if rows is None else rows
        return np.column_stack([now.k[where], now.ego[where]]).astype(np.int32)

    def model_masks(self, rows: slice | None = None) -> np.ndarray:
        """``(n, P)`` bool: the actions the model's ``allow when`` allows each episode now (all of
        them without the rule, or for a state the rule leaves none: the emitted model would deadlock
        there, an episode goes on unrestricted); of the episodes ``rows`` only, if given."""
        now, _, _ = self._require()
        where = slice(None) if rows is None else rows
        ego, k = now.ego[where], now.k[where]
        if not self.guard.restricts:
            return np.ones((ego.shape[0], self.n_actions), dtype=bool)
        masks = self.guard.masks(ego, k)
        masks[~masks.any(axis=1)] = True
        return masks

    @property
    def memo_bytes(self) -> int:
        """The bytes this batch's memo of steps taken holds (0 without one); all memos of the process
        hold at most :data:`rac.engine.budget.EPISODE_MEMO_BYTES` together."""
        return self._transitions.share.bytes if self._transitions is not None else 0

    @property
    def location(self) -> np.ndarray:
        """``(n,)`` the automaton's location index per episode (into ``automaton.location_names``)."""
        return self._require()[0].location.copy()

    @property
    def rewards(self) -> dict[str, np.ndarray]:
        """Reward name -> ``(n,)`` its value per episode (after ``at end`` for ended episodes)."""
        return {name: values.copy() for name, values in self._require()[0].rewards.items()}

    @property
    def inputs(self) -> dict[str, np.ndarray]:
        """Input name -> ``(n,)`` the value read at the current sample (at sample 0: the bindings on the start)."""
        return {name: values.copy() for name, values in self._require()[0].inputs.items()}

    @property
    def objective(self) -> np.ndarray:
        """``(n,)`` the objective's value per episode."""
        return self._require()[2].objective

    def expression(self, expr: Expression) -> ie.Expr:
        """``expr`` checked against the automaton (text or a parsed node; a boolean counts as 0 or 1 in
        arithmetic), or as it is when checked: :class:`rac.core.diagnostics.CheckError` for an unknown
        name or a type error, :class:`ValueError` when the text is not one expression."""
        if isinstance(expr, str | ast.Number | ast.BoolLit | ast.Name | ast.Qualified | ast.Call | ast.Unary
                      | ast.Binary):
            return lower_expression(self.automaton, expr, bool_numbers=True)
        return expr

    def observe(self, exprs: Sequence[Expression], rows: slice | None = None) -> np.ndarray:
        """``(n, len(exprs))`` float64: each expression in every episode's current frame (booleans
        0/1); of the episodes ``rows`` only, if given. An expression may read the model's vocabulary
        (ego names, ``time``, ``mindist()`` ...), the inputs, rewards and locations
        (``Driving.location``, ``Unsafe``) and ``prev(e)``."""
        now, prev, _ = self._require()
        where = slice(None) if rows is None else rows
        frame = now.frame(where, prev=prev.frame(where))
        out = np.empty((frame.n, len(exprs)), dtype=np.float64)
        for column, value in enumerate(self._observer(exprs)(frame)):
            out[:, column] = value
        return out

    def ahead(self, exprs: Sequence[Expression], rows: slice | np.ndarray | None = None,
              actions: np.ndarray | None = None) -> np.ndarray:
        """``(n, n_actions, len(exprs))`` float64: each expression one decision later, had the episode
        taken each action now (as :meth:`observe` would read it after :meth:`step`); NaN for an episode
        that is done; of the episodes ``rows`` only (a slice or indices), if given. The batch is not
        changed: the steps are taken by a copy of the episodes, one per action asked (``actions``: a
        ``(len(rows), n_actions)`` mask, the others NaN; default every action of the model's, whether or
        not ``allow when`` or a shield allows it), counted in :attr:`steps_ahead`; the memo keeps them,
        so the step then taken is recalled. For exploration steered by the model
        (:class:`rac.learning.tabular.Learner`, :class:`rac.learning.runs.Ahead`)."""
        self._require()
        where = np.arange(self.n)[slice(None) if rows is None else rows]
        out = np.full((where.size, self.n_actions, len(exprs)), np.nan)
        wanted = np.ones((where.size, self.n_actions), dtype=bool) if actions is None else np.asarray(actions, bool)
        if wanted.shape != out.shape[:2]:
            raise ValueError(f"actions must be a ({where.size}, {self.n_actions}) mask, not {wanted.shape}")
        row, action = np.nonzero(wanted & ~self.done[where][:, None])
        if row.size == 0:
            return out
        # a shallow copy: it shares the model, the compiled expressions and the memo, and select()
        # gives it its own episodes; what step() changes in place is made its own here
        probe = copy.copy(self)
        probe.counterfactuals = False
        probe.clipped_inputs = dict(self.clipped_inputs)
        probe._record = []
        probe.select(where[row])
        probe.step(action)
        out[row, action] = probe.observe(exprs)
        self.steps_ahead += (probe.steps_recalled + probe.steps_computed) - (self.steps_recalled + self.steps_computed)
        return out

    def _observer(self, exprs: Sequence[Expression]) -> Callable[[Frame], list[np.ndarray]]:
        """The function giving ``exprs``' values, checked and compiled the first time (learners observe
        the same expressions at every step); kept for up to 64 distinct lists."""
        try:
            key = tuple(exprs)
            known = self._observers.get(key)
        except TypeError:  # an unhashable node: checked and compiled each time
            return self._compile([self.expression(expr) for expr in exprs])
        if known is None:
            if len(self._observers) >= 64:
                self._observers.clear()
            known = self._observers[key] = self._compile([self.expression(expr) for expr in exprs])
        return known

    # ------------------------------------------------------------ stepping
    def step(self, actions: np.ndarray) -> StepResult:
        """One decision period for every episode not done: ``actions`` ``(n,)`` are indices into
        :attr:`action_pairs` (those of done episodes are ignored)."""
        now, _, _ = self._require()
        actions = np.asarray(actions)
        if actions.shape != (self.n,) or not np.issubdtype(actions.dtype, np.integer):
            raise ValueError(f"actions must be an integer array of shape ({self.n},), not {actions.dtype} "
                             f"{actions.shape}")
        n = self.n
        reward = np.zeros(n)
        flags = {name: np.zeros(n, dtype=bool) for name in ("terminated", "truncated", "collided", "offroad",
                                                              "stranded", "ended")}
        live = ~self.done
        chosen = actions[live]
        if chosen.size and (chosen.min() < 0 or chosen.max() >= self.n_actions):
            raise ValueError(f"actions must be in [0, {self.n_actions}), got {chosen.min()}..{chosen.max()}")
        pairs = np.zeros((n, 2), dtype=np.int32)
        pairs[live] = self.action_pairs[chosen]
        if self.counterfactuals:
            self._before, self._record = now.copy(), []
        if self._transitions is not None:
            self._recalling(self._transitions, pairs, reward, flags)
        else:
            self.steps_computed += int((~self.done).sum())
            for _ in range(self.decide_every):
                rows = np.flatnonzero(~self.done)
                if rows.size == 0:
                    break
                self._sample(rows, pairs, reward, flags)
        self._last_reward = reward.copy()
        return StepResult(reward=reward, **flags)

    def counterfactual(self, rows: slice | None = None, objective: Expression | None = None) -> Counterfactuals:
        """The last :meth:`step` replayed from every location of the automaton, for the episodes
        ``rows`` (default all): per episode and location, the step's reward had the automaton been
        there when the step began, and the location it would have reached
        (:mod:`rac.learning.counterfactual`; the episodes must have been made with
        ``counterfactuals=True``). The reward is the batch's: the objective's increase, or with
        ``objective`` that expression's increase (as :class:`rac.learning.qlearning.ObjectiveIncrease`
        rewards a step), or a reward expression's value, which must then not read the automaton's
        locations or rewards (it is the same in every location). ``ValueError`` when the goal reads
        them (the episode's end would depend on the location)."""
        now, _, _ = self._require()
        before = self._before
        if not self.counterfactuals or before is None:
            raise RacValueError("no step recorded: make the episodes with counterfactuals=True and step them first")
        if self.goal is not None and _reads_location_or_rewards(self.goal):
            raise RacValueError("counterfactual experiences need a goal that does not read the automaton's locations "
                                "or rewards")
        where = slice(None) if rows is None else rows
        n = int(now.k[where].shape[0])
        whole = self._replayed(before)
        cf = Counterfactuals(whole.reward[where].copy(), whole.next_location[where].copy(),
                             {name: values[where].copy() for name, values in whole.rewards.items()})
        if objective is not None:
            expr = self.expression(objective)
            size = cf.n_locations
            spread = np.repeat(np.arange(n), size)
            locations = np.tile(np.arange(size), n)
            start = _spread(before, where, spread, locations,
                            {name: np.repeat(values[where], size) for name, values in before.rewards.items()})
            end = _spread(now, where, spread, cf.next_location.reshape(-1),
                          {name: values.reshape(-1) for name, values in cf.rewards.items()}, prev=start)
            gain = (np.asarray(self.evaluator.evaluate(expr, end), dtype=np.float64)
                    - np.asarray(self.evaluator.evaluate(expr, start), dtype=np.float64)).reshape(n, size)
            ran = np.repeat(np.asarray(self._record[0].active[where] if self._record else np.zeros(n, bool)), size)
            return dataclasses.replace(cf, reward=np.where(ran.reshape(n, size), gain, 0.0))
        if self.reward_expr is not None:
            if _reads_location_or_rewards(self.reward_expr):
                raise RacValueError("counterfactual experiences of a reward expression that reads the automaton's "
                                    "locations or rewards are not supported: pass the automaton's objective")
            reward = np.repeat(self._last_reward[where][:, None], cf.n_locations, axis=1)
            return dataclasses.replace(cf, reward=reward)
        return cf

    def _replayed(self, before: _State) -> Counterfactuals:
        """The last step replayed from every location for *all* the batch's episodes, computed at the
        first :meth:`counterfactual` after the step and kept for the others: learners sharing the batch
        (:mod:`rac.learning.lockstep`) each ask for their own rows, and one replay of every row costs
        about what one of a few rows does. A row's replay reads that row alone (the automata are
        stepped elementwise), so its slice of the whole is what replaying its rows alone gives, bit for
        bit (tests/learning/test_counterfactual.py checks it)."""
        kept = self._replay_kept
        if kept is not None and kept[0] is self._record and kept[1] is before:
            return kept[2]
        samples = self._record
        n = int(before.k.shape[0])
        # the first sample's rates read the inputs held from the sample before the step (its own at an
        # episode's first sample, k = 0): replayed with none held, they read that first sample's inputs
        started = before.k > 0
        held = None if not samples else {
            name: np.where(started, before.inputs[name], values)
            for name, values in samples[0].inputs.items() if name in before.inputs and values.dtype != bool}
        cf = self._replayer.replay(samples, n, before.rewards, held)
        self._replay_kept = (samples, before, cf)
        return cf

    def _recalling(self, memo: _Transitions, pairs: np.ndarray, reward: np.ndarray,
                   flags: dict[str, np.ndarray]) -> None:
        """One step's samples: the model's part recalled for the episodes whose step is kept in
        ``memo``, computed (and then kept) for the others; the automaton's part for all."""
        now = self._require()[0]
        live = np.flatnonzero(~self.done)
        keys = memo.keys(now.k[live], now.ego[live], now.crashed[live], pairs[live])
        slots = memo.find(keys)
        kept = slots >= 0
        hits, hit_slots = live[kept], slots[kept]
        misses = live[~kept]
        self.steps_recalled += int(hits.size)
        self.steps_computed += int(misses.size)
        records = np.zeros((misses.size, self.decide_every), dtype=memo.dtype)
        taken = np.zeros(misses.size, dtype=np.int64)
        recalled = memo.taken(hit_slots)  # every sample of the recalled steps, gathered once
        together = self._together(misses, pairs, min(self.decide_every,
                                                     self.horizon_samples - int(now.k[misses].min()))) \
            if misses.size else None
        carry: tuple[int, np.ndarray, np.ndarray] | None = None  # the last sample taken together's rows: _carried
        for j in range(self.decide_every):
            rows = np.flatnonzero(~self.done)
            if rows.size == 0:
                break
            going = ~self.done[misses]
            computing = misses[going]
            parts: list[tuple[np.ndarray, _ModelSample]] = []
            carry = None
            if computing.size:
                if together is not None and j < together.samples:
                    computed = together.sample(j, going)
                    carry = (j, going, computing)
                else:
                    computed = self._model_sample(computing, pairs)
                memo.record(records, going, j, computed)
                taken[going] = j + 1
                parts.append((computing, computed))
            recalling = ~self.done[hits]
            if hits.size and recalling.all():  # a view of the column (nothing writes to `recalled`)
                parts.append((hits, memo.recall(recalled[:, j])))
            elif recalling.any():
                parts.append((hits[recalling], memo.recall(recalled[recalling, j])))
            self._apply(rows, _merged(rows, parts), reward, flags)
            # prev(e)'s model functions are handed on for the computed rows only: a recalled row's are not known
            if computing.size and computed.frame is not None:
                self._carry(computing, computed.frame)
            else:  # (a sample taken together hands its functions on below, if it is the last)
                self._carried = None
        if carry is not None and together is not None:  # the last sample was taken together: its functions
            self._carried = (carry[2], together.functions(carry[0], carry[1]))
        if misses.size:  # a step the automaton ended early did not run to its model's end: not kept
            last = records[np.arange(misses.size), np.maximum(taken - 1, 0)]
            whole = (taken == self.decide_every) | ((taken > 0) & last["reached"]) \
                | (now.k[misses] >= self.horizon_samples)
            memo.add([keys[i] for i in np.flatnonzero(~kept)[whole]], records[whole])

    def _sample(self, rows: np.ndarray, pairs: np.ndarray, reward: np.ndarray, flags: dict[str, np.ndarray]) -> None:
        """One sample ``k -> k + 1`` of the episodes ``rows``, each at its own ``k`` (the model's
        functions and the evaluator read ``k`` per row; after :meth:`reset_rows` the rows differ)."""
        sampled = self._model_sample(rows, pairs)
        self._apply(rows, sampled, reward, flags)
        assert sampled.frame is not None
        self._carry(rows, sampled.frame)

    def _carried_on(self, rows: np.ndarray) -> dict[str, np.ndarray]:
        """The model functions of the state computed at the last sample (or the start) on the episodes
        ``rows``, when it computed them on all of those rows (:meth:`_carry`); else none."""
        if self._carried is None:
            return {}
        carried, known = self._carried
        where = np.minimum(np.searchsorted(carried, rows), max(carried.size - 1, 0))
        if not (carried.size and np.array_equal(carried[where], rows)):
            return {}
        return {name: column[where] for name, column in known.items()}

    def _together(self, rows: np.ndarray, pairs: np.ndarray, samples: int) -> _Together | None:
        """The model's part of the next ``samples`` samples of the episodes ``rows`` (a memoised batch's,
        :meth:`_memoisable`), taken together: the ego moves sample by sample (``sense``), then every
        binding, label, goal and reward expression is read once on all those samples' states (one frame
        of ``samples * m`` rows) instead of once per sample. Each value is :meth:`_model_sample`'s, bit for
        bit: the model's functions and the compiled expressions work row by row, and a sample's model
        part reads its row's state, sample, pair and earlier collisions alone (``crashed``: or-ed along
        the samples here). Samples past an episode's end are computed but not read; where anything
        raises (a value beyond int32 there, say), None: the caller takes the samples one by one, which
        raise where the episode really reaches. None as well beyond :data:`_TOGETHER_ROWS` rows."""
        if samples < 1 or samples * rows.size > _TOGETHER_ROWS:
            return None
        now = self._require()[0]
        evaluator = self.evaluator
        m = rows.size
        egos = np.empty((samples + 1, m, now.ego.shape[1]), dtype=now.ego.dtype)
        egos[0] = now.ego[rows]  # the state before the choice: what the first sample's prev(e) reads
        ks = now.k[rows][None, :] + np.arange(samples + 1)[:, None]
        try:
            moved = egos[0].copy()
            moved[:, ACTION] = pairs[rows]
            for j in range(samples):
                moved = egos[j + 1] = evaluator.model.sense(moved)
            k, ego = ks[1:].reshape(-1), egos[1:].reshape(-1, egos.shape[2])
            mindist = evaluator.function("mindist", Frame(k=k, ego=ego))  # before the frame: collide() so far needs it
            collided = collides(mindist, self._td).reshape(samples, m)
            so_far = np.empty((samples, m), dtype=bool)  # collide() so far: before each sample, as now.crashed
            so_far[0] = now.crashed[rows]
            np.logical_or(so_far[0], np.logical_or.accumulate(collided[:-1], axis=0), out=so_far[1:])
            crashed = so_far.reshape(-1)
            carried = self._carried_on(rows)

            def earlier(name: str) -> np.ndarray:
                """A model function on the samples' prev states: the last sample's (carried, or computed on
                it), then the samples' own but the last (computed once for the frame)."""
                first = carried.get(name)
                if first is None:
                    first = evaluator.function(name, Frame(k=ks[0], ego=egos[0], crashed=crashed[:m]))
                return np.concatenate([first, evaluator.function(name, frame)[:-m]])

            before = Frame(k=ks[:-1].reshape(-1), ego=egos[:-1].reshape(-1, egos.shape[2]), crashed=crashed,
                           functions=earlier)
            frame = Frame(k=k, ego=ego, prev=before, crashed=crashed)  # (read by `earlier` when called)
            frame.keep("mindist", mindist)
            changes: dict[str, np.ndarray] = {}
            values = self._bindings.read(frame, changes=changes)
            offroad = np.asarray(evaluator.function("offroad", frame), dtype=bool)
            sampled = _ModelSample(ego, values, changes, collided.reshape(-1), offroad, frame)
            sampled.late(self._after_edge(frame.reading(values)), self.reward_expr is not None, self.goal is not None)
        except (RacError, ValueError, ArithmeticError):
            return None
        assert sampled.reached is not None
        known = frame.known()

        def split(column: np.ndarray) -> np.ndarray:
            return column.reshape(samples, m, *column.shape[1:])

        return _Together(split(ego), {name: split(v) for name, v in values.items()},
                      {name: split(v) for name, v in changes.items()}, collided, split(offroad),
                      split(sampled.reached), None if sampled.reward is None else split(sampled.reward),
                      {name: split(known[name]) for name in _OF_THE_STATE if name in known})

    def _model_sample(self, rows: np.ndarray, pairs: np.ndarray) -> _ModelSample:
        """The model's part of one sample of the episodes ``rows`` (steps 1 and 2 of the module
        docstring, the labels, and the goal and reward expression when they read the model and the
        inputs only): a function of each row's :meth:`_Transitions.keys`, nothing else."""
        now = self._require()[0]
        evaluator = self.evaluator
        # the state at k, before the choice: what prev(e) reads (a memoisable batch's prev(e) reads the
        # model alone, :meth:`_memoisable`: no location, reward or input to gather)
        before = now.frame(rows) if self._transitions is None else \
            Frame(k=now.k[rows], ego=now.ego[rows], crashed=now.crashed[rows])
        for name, column in self._carried_on(rows).items():
            before.keep(name, column)
        moved = now.ego[rows].copy()
        moved[:, ACTION] = pairs[rows]
        after = evaluator.model.sense(moved)
        frame = Frame(k=before.k + 1, ego=after, prev=before, crashed=before.crashed)
        changes: dict[str, np.ndarray] = {}
        values = self._bindings.read(frame, changes=changes)
        # the labels through the evaluator: the frame's one mindist() and offroad(), shared with the bindings
        collided = collides(evaluator.function("mindist", frame), self._td)
        offroad = np.asarray(evaluator.function("offroad", frame), dtype=bool)
        sampled = _ModelSample(after, values, changes, collided, offroad, frame)
        if self._transitions is not None:  # the goal and reward read no location, reward or held input
            sampled.late(self._after_edge(frame.reading(values)), self.reward_expr is not None,
                         self.goal is not None)
        return sampled

    def _apply(self, rows: np.ndarray, sampled: _ModelSample, reward: np.ndarray,
               flags: dict[str, np.ndarray]) -> None:
        """The automaton's part of one sample of the episodes ``rows`` (steps 3 and 4 of the module
        docstring), with the model's part ``sampled``."""
        now, prev, automata = self._require()
        active = np.zeros(self.n, dtype=bool)
        active[rows] = True
        fed = {name: held.copy() for name, held in now.inputs.items()}  # frozen episodes: their last inputs
        for name, column in sampled.values.items():
            fed[name][rows] = column
        try:
            gain = automata.step_batch(fed, mask=active)
        except ValueError as exc:
            raise RacValueError(f"sample {int(now.k[rows].min()) + 1}: the bindings' values are not valid inputs of "
                                f"`{self.automaton.name}`: {exc}") from None
        for name, changed in sampled.changes.items():
            count = int(changed.sum())
            self.clipped += count
            self.clipped_inputs[name] += count
        # the new sample becomes the current state; the old one prev(e)'s
        prev.put(active, now)
        now.k[rows] += 1
        now.ego[rows] = sampled.after
        now.inputs = fed
        self._sync(now, automata)
        now.crashed[rows] |= sampled.collided
        flags["collided"][rows] |= sampled.collided
        flags["offroad"][rows] |= sampled.offroad
        if sampled.reached is None:  # the goal or the reward reads the automaton: after its edge
            assert sampled.frame is not None
            late = self._after_edge(sampled.frame.reading(
                sampled.values, now.location[rows], {name: values[rows] for name, values in now.rewards.items()}))
            sampled.late(late, self.reward_expr is not None, self.goal is not None)
        assert sampled.reached is not None
        if self.reward_expr is None:
            reward[rows] += gain[rows]
        else:
            assert sampled.reward is not None
            reward[rows] += sampled.reward
        reached = sampled.reached
        last = now.k[rows] >= self.horizon_samples
        ended = automata.terminated[rows]  # `episode ends when`: the automaton ended the run (end clauses applied)
        ending = reached | last | ended
        if self.counterfactuals:
            ends = np.zeros(self.n, dtype=bool)
            ends[rows[ending]] = True
            self._record.append(Sample({name: values.copy() for name, values in fed.items()}, active, ends))
        if ending.any():
            flags["terminated"][rows[reached]] = True
            if self.onward is not None and reached.any():
                arrived = rows[reached]
                keys = np.column_stack([now.k[arrived], now.ego[arrived]]).astype(np.int32)
                flags["stranded"][arrived] = ~np.asarray(self.onward(keys), dtype=bool)
            flags["truncated"][rows[last & ~reached & ~ended]] = True
            flags["ended"][rows[ended]] = True
            mask = np.zeros(self.n, dtype=bool)
            mask[rows[ending]] = True
            bonus = automata.end_batch(fed, mask=mask)  # 0.0 where the automaton has ended the run itself
            if self.reward_expr is None:
                reward[mask] += bonus[mask]
            self._sync(now, automata)
            self.done[mask] = True

    @staticmethod
    def _sync(now: _State, automata: BatchRewardAutomaton) -> None:
        """The automaton's location and rewards into the current state (copies; frozen ones unchanged)."""
        now.location = automata.locations.astype(np.int64, copy=False)  # a copy already
        now.rewards = automata.rewards

    def __repr__(self) -> str:
        return (f"<EpisodeBatch {self.automaton.name} n={self.n} horizon={self.horizon_samples} samples, "
                f"{self.n_actions} actions every {self.decide_every}>")
