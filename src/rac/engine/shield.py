"""Safety shields saved to a file and used from a training loop.

``rac.engine.shield.save(shield, path)`` writes the most permissive safe strategy computed by
:func:`rac.engine.storm.safety_shield` (``strategy safe = control: A[] ...``);
``rac.engine.shield.load(path)`` reads it back as a :class:`ShieldTable`::

    table = rac.engine.shield.load("safe.shield.npz")
    mask = table.mask(state)          # (n_actions,) bool: the actions allowed in `state`
    ok = table.allowed(state)         # the allowed action indices

A state is the integer vector of the explored model (``table.columns``, e.g.
``k, x, y, v, acc, head, jerk, turn``). Only decision states are stored.

**States the shield has never seen.** The shield was computed on the states the model can
reach; a state outside them (a different start, a sensor reading the model cannot produce)
is *unseen*. What to do then is the caller's choice, made once when loading:

- ``unseen="none"`` (default): nothing is known to be safe, so no action is allowed (an empty
  mask). A masked learner must then fall back to a safe manoeuvre of its own;
- ``unseen="all"``: every action is allowed (the shield does not restrict unseen states);
- ``unseen="error"``: raise :class:`UnseenState`.

**A shield for every step** (:class:`StepShield`): the table where it applies, the runtime shield
(:mod:`rac.engine.lookahead`: a safe continuation for the next ``depth`` decisions) elsewhere —
beyond the table's horizon, in a state it has not seen, where it allows nothing, or when it could
not be computed at all (:func:`step_shield`). Each answer (:class:`ShieldStep`) says which guarantee
its mask carries, and is never an all-False mask::

    shield = step_shield(data, horizon_samples=40, table_horizon=20)   # the table if it can be had
    step = shield.decide(state)        # state: k, x, y, v, acc, head, jerk, turn
    step.mask, step.guarantee          # e.g. "exhaustive", "lookahead 5", "none"
"""

from __future__ import annotations

import warnings
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, ClassVar, Literal

import numpy as np

from rac.core.diagnostics import RacError, RacValueError
from rac.core.files import atomic_write
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.budget import BudgetExceeded, default_max_bytes
from rac.engine.explore import explore, forgets_actions
from rac.engine.lookahead import Lookahead, LookaheadMask, LookaheadSettings
from rac.engine.storm import Shield, safety_shield
from rac.model.sample import GRAPH_ACTION, GRAPH_EGO, GraphColumn

if TYPE_CHECKING:
    from rac.model.data import ModelData

FORMAT = "rac-shield-1"
UNSEEN_POLICIES = ("none", "all", "error")


class UnseenState(RacError, KeyError):
    """The shield has no entry for this state (``unseen="error"``)."""


@dataclass(frozen=True)
class ShieldTable:
    """A loaded shield: per decision state, a mask over the action indices."""

    columns: tuple[str, ...]
    states: np.ndarray  # (s, d) int32, decision states
    masks: np.ndarray  # (s, n_actions) bool
    unseen: str = "none"
    #: > 0: the shield was computed with ``explore(..., forget_actions=True)``, so a state at a sample
    #: ``k`` with ``k % forget_every == 0`` is looked up with its ``jerk`` and ``turn`` as 0 (the action
    #: that led to it, which no later step reads); 0: states are looked up as they are.
    forget_every: int = 0
    #: The sample the shield was computed to: an allowed action has a safe continuation up to it
    #: (None: not recorded, e.g. a file written before it was; then taken to cover every run).
    horizon: int | None = None
    #: :attr:`rac.model.data.ModelData.digest` of the model it was computed for (None: not recorded,
    #: a file written before it was, a table built by hand); :class:`StepShield` refuses a table of
    #: another model, and warns of one that records none.
    model: str | None = None
    #: Where it was read from (:func:`load`), for messages.
    origin: str | None = None
    #: Its rows are all it knows, so :func:`save` can write it (a shield that computes its rows when
    #: asked, :class:`rac.engine.ondemand.OnDemandShield`, has none to write).
    savable: ClassVar[bool] = True

    def __post_init__(self) -> None:
        if self.unseen not in UNSEEN_POLICIES:
            raise ValueError(f"unseen must be one of {UNSEEN_POLICIES}, not {self.unseen!r}")
        index = {row.tobytes(): i for i, row in enumerate(np.ascontiguousarray(self.states, dtype=np.int32))}
        object.__setattr__(self, "_index", index)

    @property
    def n_actions(self) -> int:
        return int(self.masks.shape[1])

    def _keys(self, rows: np.ndarray) -> np.ndarray:
        """``rows`` ``(n, d)`` as the table keys them (see :attr:`forget_every`). A row that cannot be a
        state of the table — another width, or values that are no whole numbers (an observation in
        metres and seconds) — is a :class:`~rac.core.diagnostics.RacValueError`: looked up as it is, it
        would be an unseen state, whose mask (empty, or every action) says nothing of the shield."""
        given = np.asarray(rows)
        width = given.shape[-1] if given.ndim else 1
        if given.ndim > 2 or width != len(self.columns) or (
                np.issubdtype(given.dtype, np.floating) and not np.all(np.mod(given, 1) == 0)):
            got = (f"{width} values" if width != len(self.columns) or given.ndim > 2
                   else "values that are not whole numbers")
            raise RacValueError(f"a state of this shield is a row of {len(self.columns)} integers "
                                f"({', '.join(self.columns)}: the model's significands, as "
                                f"rac.learning.episodes.EpisodeBatch.state_keys() gives them; a ScenarioEnv's "
                                f"env.unwrapped.episodes.state_keys()[0]), not {got}: an observation is no shield "
                                "state")
        rows = np.array(given, dtype=np.int32, ndmin=2)
        if self.forget_every > 0 and "k" in self.columns:
            forgotten = rows[:, self.columns.index("k")] % self.forget_every == 0
            for name in ("jerk", "turn"):
                if name in self.columns:
                    rows[forgotten, self.columns.index(name)] = 0
        return np.ascontiguousarray(rows)

    def _row(self, state: object) -> int | None:
        key = self._keys(np.asarray(state))[0].tobytes()
        return self._index.get(key)  # type: ignore[attr-defined]

    def mask(self, state: object) -> np.ndarray:
        """``(n_actions,)`` bool: the actions allowed in ``state`` (the MaskablePPO convention)."""
        row = self._row(state)
        if row is not None:
            return self.masks[row].copy()
        if self.unseen == "error":
            raise UnseenState(f"the shield has no entry for state {list(np.asarray(state).tolist())}")
        return np.full(self.n_actions, self.unseen == "all")

    def allowed(self, state: object) -> np.ndarray:
        """The allowed action indices in ``state`` (see the module docstring for unseen states)."""
        return np.flatnonzero(self.mask(state))

    def knows(self, state: object) -> bool:
        """Whether ``state`` is one of the shield's decision states."""
        return self._row(state) is not None

    def fallback_for(self, states: np.ndarray) -> np.ndarray:
        """``(n, n_actions)`` bool: where :meth:`masks_for` allows nothing, the actions known to stay
        safe the longest, if the shield knows any (an exhaustive table knows none: all False). A
        learner or a simulation that has to choose there chooses among these before all actions."""
        return np.zeros((np.array(states, ndmin=2).shape[0], self.n_actions), dtype=bool)

    def masks_at(self, k: int, states: np.ndarray) -> np.ndarray:
        """:meth:`masks_for` of the ego rows ``states`` ``(n, 7)`` at sample ``k``: the
        ``policy(k, states)`` that :func:`rac.engine.simulate.simulate` takes."""
        states = np.asarray(states, dtype=np.int32)
        return self.masks_for(np.column_stack([np.full(states.shape[0], k, dtype=np.int32), states]))

    def masks_for(self, states: np.ndarray) -> np.ndarray:
        """``(n, n_actions)`` bool: :meth:`mask` of every row of ``states`` (``(n, d)``), in one call.

        Unseen rows follow the table's ``unseen`` policy (``"error"`` raises for the first one)."""
        rows = self._keys(np.asarray(states))
        found = np.array([self._index.get(row.tobytes(), -1) for row in rows], dtype=np.int64)  # type: ignore[attr-defined]
        out = np.empty((rows.shape[0], self.n_actions), dtype=bool)
        seen = found >= 0
        out[seen] = self.masks[found[seen]]
        if not seen.all():
            if self.unseen == "error":
                raise UnseenState(f"the shield has no entry for state {rows[~seen][0].tolist()}")
            out[~seen] = self.unseen == "all"
        return out


class SafeOnward:
    """Whether a run can stay safe from a state to the horizon: the state is winning in the safety
    game of ``shield`` (``control: A[] !collide() && !offroad()`` up to ``horizon_samples``), read off
    its graph. Called with ``(m, 8)`` state keys ``k, x, y, v, acc, head, jerk, turn``; a state the
    graph does not hold (none a safe run reaches) is not. ``forget_every``: the graph was explored
    with ``forget_actions`` (:func:`rac.engine.explore.forgets_actions`), so such keys are looked up
    with jerk and turn at 0 where it holds them so (default: as the graph records,
    :attr:`rac.engine.graph.ExploredGraph.forget_every`). Used by ``rac experiment`` to judge a run that
    reaches the goal: "safe at the goal" means it can also stay safe to the horizon."""

    def __init__(self, shield: Shield, horizon_samples: int, forget_every: int | None = None) -> None:
        graph = shield.graph
        self.horizon = horizon_samples
        self.forget_every = graph.forget_every if forget_every is None else forget_every
        k = graph.states[:, GraphColumn.K]
        order = np.argsort(k, kind="stable")
        bounds = np.searchsorted(k[order], np.arange(horizon_samples + 2))
        self._layers = {layer: order[bounds[layer]:bounds[layer + 1]] for layer in range(horizon_samples + 1)}
        self._graph = graph
        # collision sticky: only states no collision has reached, keyed without the flag
        self._columns = [i for i, name in enumerate(graph.columns) if name != "crashed"]
        self._clean = (graph.states[:, graph.columns.index("crashed")] == 0 if "crashed" in graph.columns
                       else np.ones(graph.n_states, dtype=bool))
        self._winning = shield.winning
        self._sets: dict[int, set[bytes]] = {}

    def _winning_at(self, k: int) -> set[bytes]:
        found = self._sets.get(k)
        if found is None:
            rows = self._layers.get(k, np.zeros(0, dtype=np.int64))
            rows = rows[self._winning[rows] & self._clean[rows]]
            states = np.ascontiguousarray(self._graph.states[rows][:, self._columns], dtype=np.int32)
            found = self._sets[k] = {row.tobytes() for row in states}
        return found

    def __call__(self, keys: np.ndarray) -> np.ndarray:
        rows = np.array(keys, dtype=np.int32, ndmin=2)
        if self.forget_every > 0:
            rows[forgets_actions(rows[:, GraphColumn.K], self.forget_every, self.horizon), GRAPH_ACTION] = 0
        rows = np.ascontiguousarray(rows)
        return np.array([row.tobytes() in self._winning_at(int(row[GraphColumn.K])) for row in rows], dtype=bool)


def synthesise(data: ModelData, horizon_samples: int, *, max_states: int | None = None,
               max_bytes: int | None = None,
               progress: Callable[[int, int, int], None] | None = None) -> tuple[Shield, ShieldTable]:
    """The safety shield of ``control: A[] !collide() && !offroad()`` up to the horizon: the model
    explored with unsafe states not expanded, the most permissive strategy
    (:func:`rac.engine.storm.safety_shield`), and its table over the model's whole action grid.
    :class:`~rac.engine.budget.BudgetExceeded` (a ``MemoryError``) beyond ``max_states`` or ``max_bytes``
    (from the exploration)."""

    # The shield reads labels and choices only: states differing in the action that led to them merge.
    graph = explore(data, horizon_samples=horizon_samples, prune_unsafe=True, max_states=max_states,
                    max_bytes=max_bytes, progress=progress, forget_actions=True)
    computed = safety_shield(graph, "safe")
    return computed, table(computed, n_actions=len(action_pairs(data)), forget_every=data.decide_every,
                           horizon=horizon_samples, model=data)


def table(shield: Shield, *, n_actions: int | None = None, unseen: str = "none", forget_every: int | None = None,
          horizon: int | None = None, model: ModelData | None = None) -> ShieldTable:
    """The :class:`ShieldTable` of a computed shield (what :func:`save` writes and :func:`load` reads);
    ``model``: the model it was computed for (its digest is recorded: :attr:`ShieldTable.model`; default:
    the model the graph was explored for, :attr:`rac.engine.graph.ExploredGraph.model`);
    ``forget_every``: the model's ``decide_every`` when the graph was explored with ``forget_actions``
    (default: as the graph records it, :attr:`rac.engine.graph.ExploredGraph.forget_every`);
    ``horizon``: the sample the graph was explored to (default: its last sample); ``n_actions``: the
    masks' width (default: the largest action the graph takes, plus one), fewer than the graph's
    actions is a :class:`~rac.core.diagnostics.RacValueError`."""
    graph = shield.graph
    if forget_every is None:  # a graph explored with forget_actions holds its decision states without the action
        forget_every = graph.forget_every
    if horizon is None and graph.n_states and "k" in graph.columns:
        horizon = int(graph.states[:, graph.columns.index("k")].max())
    actions = graph.choice_action
    decision = actions >= 0
    largest = int(actions.max()) + 1 if decision.any() else 0  # the actions the graph's choices take
    if n_actions is None:
        n_actions = largest
    elif n_actions < largest:  # the mask would have no column for them: say so, not an IndexError
        raise RacValueError(f"n_actions={n_actions}, but the shield's graph has choices of action index up to "
                            f"{largest - 1} ({largest} actions at least): pass the model's number of actions, "
                            "len(action_pairs(data)), or leave n_actions out")
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    states_with_decisions = np.unique(owner[decision])
    columns = tuple(graph.columns)
    kept = list(range(len(columns)))
    if "crashed" in columns:  # collision sticky: the table holds the states no collision has reached yet,
        crashed = columns.index("crashed")  # keyed without the flag, as a training loop observes them
        states_with_decisions = states_with_decisions[graph.states[states_with_decisions, crashed] == 0]
        kept.remove(crashed)
        columns = tuple(columns[i] for i in kept)
    row_of = np.full(graph.n_states, -1, dtype=np.int64)
    row_of[states_with_decisions] = np.arange(states_with_decisions.size)
    masks = np.zeros((states_with_decisions.size, n_actions), dtype=bool)
    picked = decision & shield.allowed_choices
    masks[row_of[owner[picked]], actions[picked]] = True
    states = graph.states[states_with_decisions][:, kept].astype(np.int32)
    # the graph knows its model: a table made without model= was trusted on any other scene, unchecked
    return ShieldTable(columns, states, masks, unseen, forget_every, horizon,
                       model=graph.model if model is None else model.digest)


def save(shield: Shield | ShieldTable, path: str | Path, *, n_actions: int | None = None) -> Path:
    """Write a shield's decision states and their allowed actions to ``path`` (compressed .npz).

    The file is written to a temporary name of its own beside ``path`` and renamed
    (:func:`rac.core.files.atomic_write`), so an interrupted write never leaves a half shield behind,
    and two writers of one path never share a temporary file."""
    shield_table = shield if isinstance(shield, ShieldTable) else table(shield, n_actions=n_actions)
    if not shield_table.savable:  # its file would hold no state: every mask read back would be empty
        raise RacValueError(f"a {type(shield_table).__name__} computes its masks state by state when asked and has "
                            "no table to save; save an exhaustive shield (synthesise, or rac verify within its "
                            "budget)")
    return atomic_write(path, lambda handle: np.savez_compressed(
        handle, format=np.array(FORMAT), columns=np.array(shield_table.columns),
        states=shield_table.states.astype(np.int32), masks=shield_table.masks,
        forget_every=np.array(shield_table.forget_every),
        horizon=np.array(-1 if shield_table.horizon is None else shield_table.horizon),
        model=np.array("" if shield_table.model is None else shield_table.model)))


def load(path: str | Path, *, unseen: str = "none") -> ShieldTable:
    """Read a shield written by :func:`save`; ``unseen`` says what unknown states get."""
    path = Path(path)
    try:
        with np.load(path, allow_pickle=False) as data:
            if "format" not in data.files:  # another .npz: a learned strategy (the same folder holds both), arrays
                other = ("a rac strategy (rac.learning.qlearning.LearnedStrategy.load reads it)"
                         if "header" in data.files else f"arrays {', '.join(data.files) or 'none'}")
                raise RacValueError(f"{path}: not a rac shield: {other}")
            if str(data["format"]) != FORMAT:
                raise RacValueError(f"{path}: not a rac shield (format {str(data['format'])!r})")
            forget_every = int(data["forget_every"]) if "forget_every" in data.files else 0
            horizon = int(data["horizon"]) if "horizon" in data.files else -1
            model = str(data["model"]) if "model" in data.files else ""
            return ShieldTable(tuple(str(c) for c in data["columns"]), data["states"].astype(np.int32),
                               data["masks"].astype(bool), unseen, forget_every, None if horizon < 0 else horizon,
                               model=model or None, origin=str(path))
    except (OSError, KeyError, ValueError) as exc:
        if isinstance(exc, FileNotFoundError):
            raise
        raise RacValueError(f"{path}: cannot read the shield: {exc}") from None


# ---------------------------------------------------------------- a shield for every step
#: The guarantees a :class:`ShieldStep` carries (``"lookahead"`` is written with its depth: ``"lookahead 5"``).
GUARANTEES = ("exhaustive", "lookahead", "none")


@dataclass(frozen=True)
class ShieldStep:
    """What :class:`StepShield` hands out at one decision state.

    ``mask`` ``(P,)`` bool is never all False. ``guarantee`` says what it carries:

    - ``"exhaustive"``: the table's row — every allowed action has a safe continuation up to the
      table's horizon, and every action that has one is allowed (the most permissive shield);
    - ``"lookahead d"``: the runtime shield's — every allowed action has a safe continuation for the
      next ``d`` decisions (up to the sample ``until``); with ``timed_out`` its budget ran out, so
      ``d`` may fall short of the setting and the mask may leave out actions a complete search would
      allow;
    - ``"none"``: no action is known to be safe (``no_safe_action``): every action of the model
      (those its ``allow when`` permits) is allowed, no guarantee at all.
    """

    mask: np.ndarray
    guarantee: str
    #: The sample up to which every allowed action is proved to have a safe continuation (the
    #: state's own sample under ``"none"``).
    until: int
    timed_out: bool = False
    no_safe_action: bool = False
    #: The runtime shield's answer, where it was asked.
    lookahead: LookaheadMask | None = None

    @property
    def kind(self) -> str:
        """The guarantee without its depth: one of :data:`GUARANTEES`."""
        return self.guarantee.split(" ", 1)[0]

    @property
    def clock(self) -> bool:
        """The runtime shield's *time* limit stopped its search (:attr:`LookaheadMask.clock`): this mask
        depends on the machine's speed and load, so a run at the same seed may get another one."""
        return self.lookahead is not None and self.lookahead.clock

    @property
    def short(self) -> bool:
        """The runtime shield's mask reaches fewer decisions than were asked for at this state (no
        action survives all of them, or its budget ran out first)."""
        return self.lookahead is not None and self.kind == "lookahead" and self.lookahead.depth < self.lookahead.target


class StepShield:
    """The exhaustive table where it applies and the runtime shield elsewhere, for runs of
    ``horizon_samples`` samples of the model ``data`` (see the module docstring).

    At a decision state the answer with the farther guarantee wins: the table's row (when the table
    knows the state and allows an action there; it guarantees safety up to the table's horizon) or
    the runtime shield's (a continuation for the next ``depth`` decisions), which is asked only where
    it could reach farther — the table is absent, does not know the state or allows nothing there,
    or ends before the runtime shield's horizon would. Equal reach goes to the table (it is the most
    permissive). Neither: ``"none"``, the model's own allowed actions (see :class:`ShieldStep`).

    A table with ``unseen="error"`` still raises :class:`UnseenState` for a state it has not seen;
    its other policies give way to the runtime shield. ``reason``: why there is no table, if there
    is none (e.g. the exhaustive shield exceeded its budget), for reports."""

    def __init__(self, data: ModelData, horizon_samples: int, *, table: ShieldTable | None = None,
                 lookahead: LookaheadSettings | None = None, reason: str | None = None) -> None:

        self.data = data
        self.horizon = int(horizon_samples)
        self.table = table
        self.n_actions = len(action_pairs(data))
        if table is not None and table.n_actions != self.n_actions:
            raise RacValueError(f"the shield table has {table.n_actions} actions, the model {self.n_actions}")
        if table is not None and table.model is not None and table.model != data.digest:
            # its masks would be called exhaustive where they prove nothing: a stale file, another scene
            where = f"the shield {table.origin}" if table.origin else "the shield table"
            raise RacValueError(f"{where} was computed for another model (digest {table.model}, this model's "
                                f"{data.digest}): another scene, or the model block or its scenario changed since; "
                                "compute it again for this model (rac verify writes NAME.shield.npz)")
        if table is not None and table.model is None:
            # nothing to compare: its masks would be called exhaustive here whatever scene it was computed for
            where = f"the shield {table.origin}" if table.origin else "the shield table"
            warnings.warn(f"{where} does not record the model it was computed for (a table built without "
                          "rac.engine.shield.table's graph or model=, or a file written before rac recorded it), so "
                          "it cannot be checked against this one: its masks are called exhaustive here unchecked, "
                          "and a table of another scene or setting would be trusted alike; compute it again for "
                          "this model (rac.engine.shield.synthesise, or rac verify's NAME.shield.npz)", UserWarning,
                          stacklevel=2)
        self.runtime = Lookahead(data, self.horizon, lookahead) if lookahead is not None else None
        self.reason = reason
        self._guard = ActionGuard(data)

    def decide(self, state: np.ndarray, crashed: bool = False) -> ShieldStep:
        """The mask at ``state`` (``(8,)`` ``k, x, y, v, acc, head, jerk, turn``, ``k`` a decision sample
        before the horizon); ``crashed``: under ``collision sticky``, a collision happened on the way
        here (nothing that follows is safe then, so neither shield allows anything)."""
        row = np.asarray(state, dtype=np.int64).reshape(-1)
        k = int(row[GraphColumn.K])
        doomed = crashed and self.data.sticky
        table = self.table
        exhaustive: ShieldStep | None = None
        if table is not None and not doomed:
            if table.knows(row):
                mask = table.mask(row)
                # at or past its horizon a table proves nothing (an on-demand shield answers every action there)
                if mask.any() and (table.horizon is None or k < table.horizon):
                    exhaustive = ShieldStep(mask, "exhaustive", self.horizon if table.horizon is None
                                            else min(table.horizon, self.horizon))
            elif table.unseen == "error":
                table.mask(row)  # raises UnseenState, naming the state
        runtime = self.runtime
        if runtime is not None and not doomed and k < self.horizon:
            if exhaustive is None or exhaustive.until < runtime.reach(k):
                found = runtime.decide(row, crashed)
                if found.depth > 0 and (exhaustive is None or found.until > exhaustive.until):
                    return ShieldStep(found.mask, f"lookahead {found.depth}", found.until, found.timed_out,
                                      lookahead=found)
                if exhaustive is None:
                    return self._none(row, found.timed_out, found)
        return exhaustive if exhaustive is not None else self._none(row, False, None)

    def _none(self, row: np.ndarray, timed_out: bool, found: LookaheadMask | None) -> ShieldStep:
        """No action is known to be safe: the model's allowed actions (all, where ``allow when``
        leaves none: the run would stop there)."""
        mask = self._guard.masks(row[None, GRAPH_EGO].astype(np.int32), int(row[GraphColumn.K]))[0]
        if not mask.any():
            mask = np.ones(self.n_actions, dtype=bool)
        return ShieldStep(mask, "none", int(row[GraphColumn.K]), timed_out, no_safe_action=True, lookahead=found)


class StepShieldPolicy:
    """A :class:`StepShield` as a simulation policy (:data:`rac.engine.simulate.Policy`): at decision
    sample ``k`` each run's mask is the step shield's at its state. It counts the guarantees the masks
    carried, so a report can say how far the runs' safety was proved (:meth:`summary`)."""

    def __init__(self, shield: StepShield) -> None:
        self.shield = shield
        #: Decisions by the guarantee their mask carried (``"exhaustive"``, ``"lookahead"``, ``"none"``).
        self.kinds: dict[str, int] = {}
        #: Runtime-shield decisions that proved fewer decisions than asked (``depth < target``).
        self.short = 0
        #: Runtime-shield decisions whose search ran out of its budget (nodes or time) ...
        self.timed_out = 0
        #: ... of them, those its time budget stopped (their masks depend on the machine's speed).
        self.clocked = 0

    def __call__(self, k: int, states: np.ndarray) -> np.ndarray:
        masks = np.zeros((len(states), self.shield.n_actions), dtype=bool)
        for i, ego in enumerate(np.asarray(states, dtype=np.int64)):
            step = self.shield.decide(np.concatenate(([k], ego)))
            masks[i] = step.mask
            self.kinds[step.kind] = self.kinds.get(step.kind, 0) + 1
            self.timed_out += int(step.timed_out)
            found = step.lookahead
            self.clocked += int(step.clock)
            self.short += int(step.kind == "lookahead" and found is not None and found.depth < found.target)
        return masks

    def summary(self) -> str:
        """What the masks guaranteed over the decisions taken so far, in one sentence."""
        runtime = self.shield.runtime
        depth = runtime.settings.depth if runtime is not None else 0
        said = {"exhaustive": "by the exhaustive shield (safe to the horizon)",
                "lookahead": f"by the runtime shield (a safe continuation for the next {depth} decisions, or to "
                             "the horizon" + (f"; {self.short:,} of them for fewer" if self.short else "") + ")",
                "none": "with no action known to be safe (any action of the model)"}
        parts = [f"{self.kinds[kind]:,} {text}" for kind, text in said.items() if self.kinds.get(kind)]
        timed = f"; {self.timed_out:,} ran out of their search budget" if self.timed_out else ""
        if self.clocked:
            timed += (f" ({self.clocked:,} by its time limit, so the runs depend on the machine's speed and may "
                      "differ at the same seed)")
        return f"{sum(self.kinds.values()):,} decisions: " + ", ".join(parts) + timed


def step_shield(data: ModelData, horizon_samples: int, *, table_horizon: int | None = None,
                lookahead: LookaheadSettings | None = None, max_states: int | None = None,
                max_bytes: int | Literal["machine"] | None = "machine") -> StepShield:
    """A :class:`StepShield` for runs of ``horizon_samples`` samples: the exhaustive shield
    (:func:`synthesise`) up to ``table_horizon`` (default: the whole run; 0: none) if it can be
    computed within ``max_states`` and ``max_bytes`` (default ``"machine"``:
    :func:`~rac.engine.budget.default_max_bytes`, half the memory the process may use, as ``rac``'s
    ``--max-memory``; None: no limit), the runtime shield with ``lookahead`` (default
    :class:`~rac.engine.lookahead.LookaheadSettings`) everywhere else. When the exhaustive shield
    exceeds its budget, the result has no table and says why (:attr:`StepShield.reason`)."""

    if max_bytes == "machine":  # a table too large for the machine gives way before it swaps, not after
        max_bytes = default_max_bytes()
    until = horizon_samples if table_horizon is None else min(int(table_horizon), horizon_samples)
    settings = lookahead if lookahead is not None else LookaheadSettings()
    if until <= 0:
        return StepShield(data, horizon_samples, lookahead=settings, reason="no exhaustive shield was asked for")
    try:
        _, found = synthesise(data, until, max_states=max_states, max_bytes=max_bytes)
    except BudgetExceeded as exc:
        return StepShield(data, horizon_samples, lookahead=settings,
                          reason=f"the exhaustive shield up to sample {until} could not be computed: {exc}")
    return StepShield(data, horizon_samples, table=found, lookahead=settings)
