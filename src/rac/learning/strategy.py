"""Learned strategies: the observation key, the strategy's table and its runs' record (making runs:
:mod:`rac.learning.runs`).

A strategy learned by :func:`rac.learning.qlearning.learn` maps an *observation key* to one
Q-value per action of the episodes (:class:`rac.learning.episodes.EpisodeBatch`):

- **Observation key.** The discrete expressions' values as they are (booleans 0/1, locations by
  index), then each continuous value binned: ``floor(value / width + 1e-9)`` (the tolerance keeps
  ``0.3 / 0.1`` in bin 3). Default widths (:func:`default_bin`, :data:`DEFAULT_BINS`): 1 m for
  positions and distances (``x, y, mindist(), dist_goal()``), 0.5 m/s for speeds, 0.5 m/s² for
  accelerations, 0.5 m/s³ for the jerk, 0.1 rad for headings, 0.05 rad/s for the turn rate, 0.1 s
  for ``time``, 1 (in the expression's unit) for anything else. The key holds only what the query
  lists (the sample is not added): put ``time`` in the discrete list for a time-dependent strategy.
- **Choices.** Greedy among the *allowed* actions (the shield's mask at the state key; all
  actions without a shield; all actions where the shield allows nothing, counted as
  ``fallbacks``). Ties go to the lowest action index, so a strategy is deterministic. A caller's
  mask row that allows nothing gets the greedy action among all, with a warning (once per strategy).
- **Unseen observations.** A strategy picks the lowest-index allowed action in a state it never
  saw (its Q-values count as 0, and ties go to the lowest index).

:func:`rac.learning.runs.run_strategy` gives the strategy's run and :func:`rac.learning.runs.evaluate`
a success rate. :meth:`LearnedStrategy.save` and :meth:`LearnedStrategy.load` keep a strategy in a
``.strategy.npz`` file.
"""

from __future__ import annotations

import json
import math
import typing
import warnings
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol

import numpy as np

from rac.core.caller import user_stacklevel
from rac.core.diagnostics import RacValueError
from rac.core.files import atomic_write
from rac.core.source import SourceFile
from rac.engine.explore import action_pairs
from rac.engine.shield import ShieldTable
from rac.engine.simulate import simulate
from rac.ir import expr as ie
from rac.lang import ast
from rac.lang.parser import parse_expressions
from rac.learning.episodes import Expression
from rac.model.sample import GRAPH_LAYER_ROW, GraphColumn

if TYPE_CHECKING:  # imported when a run is replayed (the simulator is not needed before)
    from rac.engine.simulate import Runs
    from rac.model.data import ModelData

__all__ = ["DEFAULT_BIN", "DEFAULT_BINS", "Episodes", "Forwarding", "LearnedStrategy", "StepOutcome", "StrategyRun",
           "allowed_actions", "check_shield", "default_bin", "derived_bins", "empty_mask_warning", "greedy_actions",
           "key_bytes", "observation_keys", "observed_name", "uniform_allowed"]

FORMAT = "rac-strategy-1"
#: Default bin widths of continuous observations, by name (a plain name, a model function, or
#: ``fabs``/``-`` of one); see the module docstring.
DEFAULT_BINS: dict[str, float] = {
    "x": 1.0, "y": 1.0, "true_x": 1.0, "true_y": 1.0, "mindist": 1.0, "dist_goal": 1.0,
    "v": 0.5, "true_v": 0.5, "acc": 0.5, "true_acc": 0.5, "jerk": 0.5,
    "head": 0.1, "true_head": 0.1, "turn": 0.05, "time": 0.1,
}
#: The width of a continuous expression :data:`DEFAULT_BINS` does not name.
DEFAULT_BIN = 1.0
#: Added to ``value / width`` before flooring, so that float noise does not drop a value on a
#: bin's edge into the bin below.
BIN_TOLERANCE = 1e-9


class StepOutcome(Protocol):
    """What a step returns (:class:`rac.learning.episodes.StepResult`): ``(n,)`` arrays, read only."""

    @property
    def reward(self) -> np.ndarray: ...

    @property
    def terminated(self) -> np.ndarray: ...

    @property
    def truncated(self) -> np.ndarray: ...

    @property
    def collided(self) -> np.ndarray: ...

    @property
    def stranded(self) -> np.ndarray: ...

    @property
    def offroad(self) -> np.ndarray: ...

    @property
    def ended(self) -> np.ndarray: ...


class Episodes(Protocol):
    """What learning needs of :class:`rac.learning.episodes.EpisodeBatch` (tests may pass a stand-in);
    learning reads these attributes, it never sets them."""

    @property
    def n_actions(self) -> int: ...

    @property
    def decide_every(self) -> int: ...

    @property
    def horizon_samples(self) -> int: ...

    @property
    def max_steps(self) -> int: ...

    @property
    def n(self) -> int: ...

    @property
    def done(self) -> np.ndarray: ...

    def reset(self, n: int) -> None: ...

    def state_keys(self) -> np.ndarray: ...

    def model_masks(self) -> np.ndarray: ...

    def observe(self, exprs: Sequence[Expression]) -> np.ndarray: ...

    def expression(self, expr: Expression) -> ie.Expr: ...

    def step(self, actions: np.ndarray) -> StepOutcome: ...


def _forwarded(name: str) -> Any:
    """A read-only property: the attribute ``name`` of ``self.batch``."""
    return property(lambda self: getattr(self.batch, name), doc=f"``self.batch.{name}``")


class Forwarding:
    """The facts of the episodes ``self.batch`` that a view of them repeats (:class:`Episodes`'s
    ``n_actions``, ``decide_every``, ``horizon_samples``, ``max_steps``, and ``expression``)."""

    batch: Episodes
    n_actions: int = _forwarded("n_actions")
    decide_every: int = _forwarded("decide_every")
    horizon_samples: int = _forwarded("horizon_samples")
    max_steps: int = _forwarded("max_steps")

    def expression(self, expr: Expression) -> ie.Expr:
        return self.batch.expression(expr)


# ---------------------------------------------------------------- observations
def default_bin(expr: ie.Expr | ast.Expr) -> float:
    """The default bin width of a continuous observation (:data:`DEFAULT_BINS`), checked or parsed:
    by the name it observes (``v``, ``fabs(turn)``, ``-acc``)."""
    name = observed_name(expr)
    return DEFAULT_BINS.get(name, DEFAULT_BIN) if name is not None else DEFAULT_BIN


def observed_name(expr: ie.Expr | ast.Expr) -> str | None:
    """The name a continuous observation observes (``v``, ``fabs(turn)``, ``-acc``, ``dist_goal()``), or None."""
    if isinstance(expr, ie.Unary | ast.Unary) and expr.op == "-":
        return observed_name(expr.operand)
    if isinstance(expr, ie.Call) and expr.name in ("fabs", "abs") and len(expr.args) == 1:
        return observed_name(expr.args[0])
    if isinstance(expr, ast.Call) and expr.func in ("fabs", "abs") and len(expr.args) == 1:
        return observed_name(expr.args[0])
    return (expr.name if isinstance(expr, ie.Ref | ie.Call) else expr.id if isinstance(expr, ast.Name)
            else expr.func if isinstance(expr, ast.Call) else None)


def derived_bins(data: ModelData, exprs: Sequence[ie.Expr | ast.Expr]) -> tuple[float, ...]:
    """Bin widths of continuous observations derived from the model's own resolution and its goal
    (``rac experiment``'s default; issue 23): the change one step of the action grid makes over one
    decision period ``T``, so that two decisions one grid step apart lead to different bins. With
    ``dj`` the jerk grid's step and ``dw`` the turn rate's: ``jerk`` dj, ``turn`` dw, ``acc``
    dj*T, ``v`` dj*T^2/2, ``head`` dw*T, positions and distances (``x, y, dist_goal(), mindist()``)
    dj*T^3/6 but at most half the goal region's shorter side (so that the goal spans two bins
    across), ``time`` T. Any other expression, or a model without a jerk or turn grid, gets
    :func:`default_bin`."""
    scale = float(data.scale)
    period = data.decide_period / scale
    steps = {action.name: action.step / scale for action in data.actions if action.step > 0}
    xs, ys = np.array(data.goal_x[:data.goal_start[1]] if data.goal_count else [], dtype=np.float64), \
        np.array(data.goal_y[:data.goal_start[1]] if data.goal_count else [], dtype=np.float64)
    goal_side = min(np.ptp(xs), np.ptp(ys)) / scale if xs.size else math.inf
    jerk, turn = steps.get("jerk"), steps.get("turn")
    position = None if jerk is None else min(jerk * period ** 3 / 6, goal_side / 2)
    widths = {"jerk": jerk, "turn": turn, "acc": None if jerk is None else jerk * period,
              "v": None if jerk is None else jerk * period ** 2 / 2, "head": None if turn is None else turn * period,
              "x": position, "y": position, "dist_goal": position, "mindist": position, "time": period}
    out = []
    for expr in exprs:
        name = observed_name(expr)
        width = widths.get(name.removeprefix("true_")) if name is not None else None
        out.append(float(width) if width is not None and width > 0 else default_bin(expr))
    return tuple(out)


def observation_keys(values: np.ndarray, n_discrete: int, bins: Sequence[float] | np.ndarray) -> np.ndarray:
    """``(n, d + c)`` float64 keys of observed values: the ``n_discrete`` first columns as they
    are, the others binned (``floor(value / width + 1e-9)``); ``-0.0`` becomes ``0.0`` (one key)."""
    keys = np.array(values, dtype=np.float64, ndmin=2, copy=True)
    widths = np.asarray(bins, dtype=np.float64)
    if keys.shape[1] != n_discrete + widths.size:
        raise ValueError(f"{keys.shape[1]} observed values, expected {n_discrete} discrete + {widths.size} binned")
    keys[:, n_discrete:] = np.floor(keys[:, n_discrete:] / widths + BIN_TOLERANCE)
    return keys + 0.0


def key_bytes(keys: np.ndarray) -> list[bytes]:
    """Each observation key as bytes, for dictionaries of keys (float64, row by row)."""
    keys = np.ascontiguousarray(keys, dtype=np.float64)
    if keys.ndim == 2 and keys.shape[1]:  # each row as one opaque item: numpy makes the bytes, not a loop
        return typing.cast(list[bytes], keys.view(np.dtype((np.void, keys.shape[1] * keys.itemsize))).ravel().tolist())
    return [row.tobytes() for row in keys]


def greedy_actions(utilities: np.ndarray, masks: np.ndarray) -> np.ndarray:
    """The best allowed action per row; ``argmax`` takes the first maximum, so ties go to the lowest index."""
    return np.where(masks, utilities, -np.inf).argmax(axis=1).astype(np.int64, copy=False)


def uniform_allowed(rng: np.random.Generator, masks: np.ndarray) -> np.ndarray:
    """One allowed action per row, uniformly (every row allows one)."""
    # the ufuncs' and methods' own forms: the functions' dispatch costs more than the work on a few rows
    counts: np.ndarray = np.add.reduce(masks, axis=1)
    pick = rng.integers(0, counts)
    if masks.all():  # every action allowed (no shield): the pick is the action
        return pick.astype(np.int64, copy=False)
    return (masks.cumsum(axis=1) > pick[:, None]).argmax(axis=1).astype(np.int64, copy=False)


def allowed_actions(batch: Episodes, shield: ShieldTable | None,
                    keys: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """The allowed actions of every episode — the model's ``allow when`` and the shield's mask —
    and which rows fell back (the shield allowed none of them): to the actions the shield knows to
    stay safe the longest where it knows some (an on-demand shield whose search ran out of time:
    :meth:`rac.engine.shield.ShieldTable.fallback_for`), else to the model's actions. ``keys``: the
    episodes' :meth:`Episodes.state_keys` now, when the caller has them."""
    model = batch.model_masks()
    if shield is None:
        return model, np.zeros(batch.n, dtype=bool)
    if keys is None:
        keys = batch.state_keys()
    masks = np.array(shield.masks_for(keys), dtype=bool) & model
    empty = np.logical_not(masks.any(axis=1))
    if empty.any():
        longest = np.array(shield.fallback_for(keys[empty]), dtype=bool) & model[empty]
        known = longest.any(axis=1)
        masks[empty] = np.where(known[:, None], longest, model[empty])
    return masks, empty


def empty_mask_warning(empty: int, rows: int) -> str:
    """The warning of :meth:`LearnedStrategy.action` given masks with ``empty`` of ``rows`` rows allowing nothing."""
    return (f"{empty} of {rows} mask rows allowed no action: the strategy chose among every action there, so no "
            "mask (no shield's guarantee) covers those choices. rac's own masks never allow nothing (a shield that "
            "knows no safe action hands out the model's actions, flagged as info['no_safe_action'] or counted as "
            "fallbacks); pass masks that allow at least one action per row. Warned once per strategy")


def check_shield(batch: Episodes, shield: ShieldTable | None) -> None:
    """``ValueError`` unless ``shield`` (if any) has the episodes' actions."""
    if shield is not None and shield.n_actions != batch.n_actions:
        raise RacValueError(f"the shield has {shield.n_actions} actions, the episodes {batch.n_actions}")


# ---------------------------------------------------------------- the learned strategy
@dataclass(frozen=True, eq=False)
class LearnedStrategy:
    """A learned Q-table and how to observe: ``keys (S, d + c)`` observation keys (see
    :func:`observation_keys`), ``values (S, P)`` their Q-values in the objective's sense (expected
    return for ``optimise="max"``, expected cost for ``"min"``), the expressions as text, the bin
    widths and ``meta`` (JSON-ready facts: the objective, the goal, the shield, the seed...)."""

    discrete: tuple[str, ...]
    continuous: tuple[str, ...]
    bins: tuple[float, ...]
    optimise: str
    keys: np.ndarray
    values: np.ndarray
    action_pairs: np.ndarray | None = None
    meta: Mapping[str, object] = field(default_factory=dict)

    def __post_init__(self) -> None:
        if self.optimise not in ("max", "min"):
            raise ValueError(f"optimise must be 'max' or 'min', not {self.optimise!r}")
        object.__setattr__(self, "_index", {raw: i for i, raw in enumerate(key_bytes(self.keys))})
        object.__setattr__(self, "_warned_empty", False)  # empty_mask_warning given (once per strategy)

    @property
    def n_actions(self) -> int:
        return int(self.values.shape[1])

    @property
    def n_states(self) -> int:
        """How many observation keys the table holds."""
        return int(self.keys.shape[0])

    def observation_keys(self, observations: np.ndarray) -> np.ndarray:
        """The keys of ``(n, d + c)`` observed values (discrete then continuous, as :meth:`expressions`)."""
        return observation_keys(observations, len(self.discrete), self.bins)

    def expressions(self) -> tuple[ast.Expr, ...]:
        """The observed expressions, parsed back from their text (discrete first; the episodes check
        them against their automaton when observing)."""
        texts = (*self.discrete, *self.continuous)
        if not texts:
            return ()
        return parse_expressions(SourceFile("<observations>", ", ".join(texts)))

    def lookup(self, keys: np.ndarray) -> np.ndarray:
        """Each key's row in :attr:`keys`, -1 for a key never seen."""
        index: dict[bytes, int] = self._index  # type: ignore[attr-defined]
        return np.array([index.get(raw, -1) for raw in key_bytes(keys)], dtype=np.int64)

    def action(self, keys: np.ndarray, masks: np.ndarray | None = None) -> np.ndarray:
        """``(n,)`` the greedy action of every observation key among the allowed ones (``masks``
        ``(n, P)`` bool; None: all). An unseen key gets the lowest-index allowed action. A row
        allowing nothing gets the greedy action among every action, which no mask constrains: the
        first such call warns (once per strategy; :func:`empty_mask_warning`)."""
        keys = np.array(keys, dtype=np.float64, ndmin=2)
        rows = self.lookup(keys)
        sign = 1.0 if self.optimise == "max" else -1.0
        utilities = sign * self.values[np.maximum(rows, 0)] if self.n_states else np.zeros((len(rows), self.n_actions))
        utilities[rows < 0] = 0.0
        allowed = np.ones(utilities.shape, dtype=bool) if masks is None else np.array(masks, dtype=bool)
        empty = ~allowed.any(axis=1)
        if empty.any() and not self._warned_empty:  # type: ignore[attr-defined]
            # once per strategy: rac's own runs never pass such a row (allowed_actions falls back first,
            # counted as fallbacks), a caller's mask that does would otherwise lose its meaning unseen
            object.__setattr__(self, "_warned_empty", True)
            warnings.warn(empty_mask_warning(int(empty.sum()), len(rows)), UserWarning, stacklevel=user_stacklevel())
        allowed[empty] = True
        return greedy_actions(utilities, allowed)

    def act(self, observations: np.ndarray, masks: np.ndarray | None = None) -> np.ndarray:
        """:meth:`action` of raw observed values."""
        return self.action(self.observation_keys(observations), masks)

    def save(self, path: str | Path) -> Path:
        """Write the strategy to ``path`` (compressed .npz: ``keys``, ``values``, ``action_pairs`` and
        a JSON ``meta`` with the format, the expressions, bins and ``optimise``). The file is written
        under a temporary name of its own and renamed (:func:`rac.core.files.atomic_write`), so an interrupted
        write leaves no half strategy, and two writers of one path never share a temporary file."""
        path = Path(path)
        header = {"format": FORMAT, "discrete": list(self.discrete), "continuous": list(self.continuous),
                  "bins": list(self.bins), "optimise": self.optimise, "meta": dict(self.meta)}
        pairs = self.action_pairs if self.action_pairs is not None else np.zeros((0, 2), dtype=np.int64)
        return atomic_write(path, lambda handle: np.savez_compressed(
            handle, header=np.array(json.dumps(header)), keys=self.keys, values=self.values, action_pairs=pairs))

    @classmethod
    def load(cls, path: str | Path) -> LearnedStrategy:
        """Read a strategy written by :meth:`save` (``ValueError`` when the file is not one)."""
        path = Path(path)
        try:
            with np.load(path, allow_pickle=False) as data:
                if "header" not in data.files:  # another .npz: a shield (rac.engine.shield.save), a user's arrays
                    other = "a rac shield (rac.engine.shield.load reads it)" if "masks" in data.files else "no header"
                    raise RacValueError(f"{path}: not a rac strategy: {other}")
                header = json.loads(str(data["header"]))
                if header.get("format") != FORMAT:
                    raise RacValueError(f"{path}: not a rac strategy (format {header.get('format')!r})")
                pairs = data["action_pairs"]
                return cls(tuple(header["discrete"]), tuple(header["continuous"]),
                           tuple(float(b) for b in header["bins"]), header["optimise"],
                           data["keys"].astype(np.float64), data["values"].astype(np.float64),
                           pairs if pairs.size else None, header.get("meta", {}))
        except (FileNotFoundError, RacValueError):
            raise
        except (OSError, KeyError, ValueError, TypeError) as exc:
            # numpy reads a file that is no .npz archive as a pickle, which it refuses with advice to trust
            # the file: not advice for a strategy file
            why = "not a NumPy .npz archive" if "pickled" in str(exc) else str(exc)
            raise RacValueError(f"{path}: cannot read the strategy: {why}") from None


# ---------------------------------------------------------------- runs
@dataclass(frozen=True, eq=False)
class StrategyRun:
    """Runs of the episodes under a strategy, one row per run, one column per decision.

    ``states (n, S+1, 8)`` int32 the state keys ``[k, x, y, v, acc, head, jerk, turn]`` before each
    step and after the last (a finished run's row repeats its last state); ``observations (n, S+1,
    d+c)`` the observed values there; ``actions (n, S)`` (-1 after the end), ``rewards (n, S)`` (0
    after the end); per run: ``returns`` (the undiscounted sum of rewards), ``reached`` the goal,
    ``collided``, ``offroad`` (at any sample), ``stranded`` (reached the goal where no run stays safe
    to the horizon: :attr:`rac.learning.episodes.EpisodeBatch.onward`), ``fallbacks`` (decisions where
    the shield allowed nothing) and ``steps`` taken. ``decide_every`` samples per step, ``horizon_samples`` the
    episodes' horizon."""

    states: np.ndarray
    observations: np.ndarray
    actions: np.ndarray
    rewards: np.ndarray
    returns: np.ndarray
    reached: np.ndarray
    collided: np.ndarray
    offroad: np.ndarray
    stranded: np.ndarray
    fallbacks: np.ndarray
    steps: np.ndarray
    decide_every: int
    horizon_samples: int

    @property
    def n_runs(self) -> int:
        return int(self.actions.shape[0])

    @property
    def success(self) -> np.ndarray:
        """``(n,)`` the run reached the goal, never collided nor left the road, and (where the episodes
        judge it) can stay safe from the goal to the horizon."""
        return self.reached & ~self.collided & ~self.offroad & ~self.stranded

    @property
    def samples_taken(self) -> np.ndarray:
        """``(n,)`` the last sample of each run (an episode ends at the sample that reaches the goal,
        which may lie inside a decision period, or at the horizon)."""
        return self.states[:, -1, GraphColumn.K].astype(np.int64)

    def samples(self, data: ModelData, *, truth_substeps: int = 100) -> Runs:
        """Every sample of the runs (:class:`rac.engine.simulate.Runs`), replayed with
        :func:`rac.engine.simulate.simulate` forced to the runs' actions (``data``: the
        :class:`rac.model.data.ModelData`), to the longest run's last sample; beyond a run's own
        :attr:`samples_taken` its row is not part of the run. Also the ground truth.

        ``RuntimeError`` when the replay does not meet the recorded decision states."""

        horizon = int(self.samples_taken.max()) if self.n_runs else 0
        actions = np.where(self.actions >= 0, self.actions, 0)  # past a run's end: any action
        n_actions = len(action_pairs(data))

        def forced(k: int, states: np.ndarray) -> np.ndarray:
            mask = np.zeros((states.shape[0], n_actions), dtype=bool)
            mask[np.arange(states.shape[0]), actions[:, k // self.decide_every]] = True
            return mask

        runs = simulate(data, runs=self.n_runs, horizon_samples=horizon, seed=0, policy=forced,
                        truth_substeps=truth_substeps)
        rows = np.arange(self.n_runs)
        for j in range(self.states.shape[1]):
            k = self.states[:, j, GraphColumn.K].astype(np.int64)
            if not np.array_equal(runs.states[rows, k], self.states[:, j, GRAPH_LAYER_ROW]):
                raise RuntimeError(f"replaying the strategy's actions does not give its state at decision {j}")
        return runs
