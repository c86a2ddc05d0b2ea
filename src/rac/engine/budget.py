"""What an exhaustive exploration may use, and the error that stops it before it uses more.

A :class:`Budget` holds a state limit (``--max-states``) and a memory limit (``--max-memory``, or the option
:func:`rac.core.resources.memory_option` names: ``rac sweep``'s ``--task-memory``; default
:func:`default_max_bytes`: half the memory available, the machine's or a container's or ``ulimit -v``'s
limit). The explorations check it before each layer is expanded and while a layer
is being merged, so they stop *before* they allocate what exceeds it, with a :class:`BudgetExceeded`
(a ``MemoryError``) that says, in the user's
terms, how far the exploration got and what to change.

Memory is estimated, not measured: the explored graph costs :data:`GRAPH_BYTES_PER_STATE` and
:data:`GRAPH_BYTES_PER_CHOICE` (its arrays, exactly), and deciding a query on it costs
:data:`PEAK_FACTOR` times the graph (Storm's sparse MDP, its value vectors and scheduler; the
factor is measured by ``benchmarks/engine.py``: 3.7 on the paper's model at 39 M states).
Simulating runs is estimated by :func:`simulation_bytes`, learning a Q-table by :func:`learning_bytes`;
a computation refused on such an estimate, before it starts, raises :class:`EstimateExceeded`.

A :class:`TimeLimit` (``rac preanalyse --max-seconds``) is checked between steps of work and as an
exploration's per-layer ``progress``; past it, :class:`TimeExceeded`.

Example::

    budget = Budget(max_states=5_000_000, max_bytes=parse_size("8G"))
    graph = explore(data, horizon_samples=140, max_states=budget.max_states, max_bytes=budget.max_bytes)
"""

from __future__ import annotations

import math
import os
import re
import time
import weakref
from dataclasses import dataclass, field
from fractions import Fraction
from pathlib import Path

from rac.core.diagnostics import RacError, counted
from rac.core.numbers import format_bytes  # re-exported: the budgets' messages and their callers use it
from rac.core.resources import memory_option, memory_option_limits

__all__ = ["EPISODE_MEMOS", "EPISODE_MEMO_BYTES", "REPLAY_MEMOS", "MemoBytes", "MemoShare",
           "EVALUATION_BYTES_PER_RUN", "EVALUATION_BYTES_PER_SAMPLE",
           "EVALUATION_BYTES_PER_STEP", "MEMO_BYTES_PER_STEP", "GRAPH_BYTES_PER_CHOICE", "GRAPH_BYTES_PER_STATE",
           "LEARNING_BYTES_PER_EPISODE", "PEAK_FACTOR", "QTABLE_COPIES", "QTABLE_INDEX_BYTES_PER_ROW",
           "REPLAY_BYTES_PER_DECISION", "REPLAY_MEMO_BYTES", "RUN_BYTES_PER_SAMPLE",
           "PROJECTION_FROM", "PROJECTION_MARGIN", "SIMULATION_PEAK_FACTOR", "VALUE_BYTES", "Budget", "BudgetExceeded",
           "EstimateExceeded", "ProjectionExceeded", "TimeExceeded", "TimeLimit", "cgroup_limit", "check_estimate",
           "default_max_bytes", "evaluation_bytes", "format_bytes", "learning_bytes", "machine_memory", "out_of_memory",
           "parse_size", "physical_memory",
           "projected_states", "runs_within", "simulation_bytes"]

#: An explored state: 8 int32 columns (32 B), its choice offset (8 B) and 4 labels (4 B).
GRAPH_BYTES_PER_STATE = 44
#: A choice: its action and its target (int64 each).
GRAPH_BYTES_PER_CHOICE = 16
#: The peak memory of deciding a query, as a multiple of the explored graph's bytes.
PEAK_FACTOR = 4
#: A simulated run's bytes per sample (:class:`rac.engine.simulate.Runs`): the sensed state (7 int32),
#: the ground truth (5 float64) and the action chosen (int64).
RUN_BYTES_PER_SAMPLE = 7 * 4 + 5 * 8 + 8
#: One value of an expression evaluated per run and sample (float64).
VALUE_BYTES = 8
#: The peak memory of simulating runs and evaluating expressions on them, as a multiple of the runs'
#: arrays and the values (the model's and the evaluator's temporaries, the values' per-sample columns
#: before they are stacked). Measured by ``benchmarks/simulation.py`` (docs/benchmarks.md): the peak RSS
#: grows by 1.5 (16,000 runs of 100 samples) to 2.5 times the arrays (2,000 runs, where the model's
#: one-off tables weigh most); 3 keeps it an upper bound.
SIMULATION_PEAK_FACTOR = 3
#: Tabular Q-learning (:mod:`rac.learning.tabular`): the copies of a Q-table row's float64 entries (its key's
#: observations and its actions' values) that may exist at once: the table's capacity doubles (up to 2x the
#: rows, 4x while the old arrays are copied into the new), plus the frozen copies of the values that the
#: greedy evaluations choose from and the best strategy's keys and values (up to 4x more). An upper bound.
QTABLE_COPIES = 8
#: A Q-table row's entry in the table's index (a Python dict from the key's bytes to the row): the bytes
#: object's header (33 B, its 8 B per observation are counted apart), the dict's slot and the row's int.
QTABLE_INDEX_BYTES_PER_ROW = 160
#: One learning episode's decision kept for the backward replay (:class:`rac.learning.tabular.Transition`):
#: its index, table rows before and after, action, reward (int64/float64 each) and end flag; its allowed
#: actions (one byte per action) are counted apart.
REPLAY_BYTES_PER_DECISION = 5 * 8 + 1
#: One learning episode's record in the history (its return, four flags, its fallbacks), held twice: per
#: batch and concatenated at the end.
LEARNING_BYTES_PER_EPISODE = 2 * (8 + 4 + 8)
#: The most bytes the batches of episodes of one process keep together of the steps they have taken,
#: to recall them instead of calling the model again (:class:`rac.learning.episodes.EpisodeBatch`'s
#: memo; then the memos stop growing).
EPISODE_MEMO_BYTES = 32 * 2**20
#: A generous estimate of one step kept in that memo (the paper's model: 20 samples, about 0.9 kB), and
#: of its replay from every location in :data:`REPLAY_MEMO_BYTES`'s (about 0.4 kB).
MEMO_BYTES_PER_STEP = 2048
#: The most bytes the replayers of counterfactual experiences of one process keep together of the
#: replays they computed (:class:`rac.learning.counterfactual.Replayer`'s memo; then a replayer's
#: memo starts afresh).
REPLAY_MEMO_BYTES = 16 * 2**20
#: One evaluation run of a learned strategy (:func:`rac.learning.runs.evaluation_steps`: its episode's row of
#: the batch, its recorded run and their temporaries): a fixed part, a part per decision and one per sample.
#: Measured as the peak RSS over 20,000 to 80,000 runs (tests' tiny road: 8 samples, 4 decisions, 1.4-1.8 kB;
#: the highway scene: 100 samples, 5 decisions, 2.8 kB; examples/paper: 140 samples, 7 decisions, 3.2-3.6 kB);
#: these constants give about twice as much, an upper bound.
EVALUATION_BYTES_PER_RUN = 2048
EVALUATION_BYTES_PER_STEP = 512
EVALUATION_BYTES_PER_SAMPLE = 16
#: An exploration that may give up on a projection (:meth:`Budget.check_projection`) does so when the
#: horizon would have this many times the state budget at the growth seen: far enough over it that a
#: slowing growth would not bring it back within, and early enough that the layers before the budget,
#: the costliest ones, are not explored for nothing.
PROJECTION_MARGIN = 100
#: ... and only once it has explored this fraction of the state budget over at least two decisions: a
#: growth seen over a handful of states (the first decision's 9 actions) says little of the horizon.
PROJECTION_FROM = 1e-3
#: The fraction of the machine's memory the default budget allows.
DEFAULT_FRACTION = 0.5

_UNITS = {"": 1, "k": 2**10, "m": 2**20, "g": 2**30, "t": 2**40}


class MemoBytes:
    """The bytes the memos of one kind hold together in this process, against :attr:`cap`: an
    experiment's runs, or a gymnasium environment over a set of scenes, keep many memos, and the cap is
    for all of them. Each memo charges its bytes to its :class:`MemoShare`, which hands them back when
    the memo is collected."""

    def __init__(self, cap: int) -> None:
        self.cap = cap
        #: the bytes every memo of this kind holds now
        self.held = 0

    def left(self) -> int:
        """The bytes the memos may still take (below 0 when a test lowered the cap under them)."""
        return self.cap - self.held

    def share(self, owner: object) -> MemoShare:
        """A share for the memo ``owner``: its bytes come back when ``owner`` is collected."""
        return MemoShare(self, owner)


class MemoShare:
    """One memo's bytes within its :class:`MemoBytes`."""

    def __init__(self, pool: MemoBytes, owner: object) -> None:
        self.pool = pool
        #: this memo's bytes
        self.bytes = 0
        weakref.finalize(owner, self.release)  # holds this share, never the owner

    def charge(self, size: int) -> None:
        """``size`` more bytes held by the memo."""
        self.pool.held += size
        self.bytes += size

    def release(self) -> None:
        """Every byte of the memo handed back (it starts afresh, or it is gone)."""
        self.pool.held -= self.bytes
        self.bytes = 0


#: The steps taken, kept by :class:`rac.learning.episodes.EpisodeBatch`'s memos (at most :data:`EPISODE_MEMO_BYTES`).
EPISODE_MEMOS = MemoBytes(EPISODE_MEMO_BYTES)
#: The replays of counterfactual experiences, kept by :class:`rac.learning.counterfactual.Replayer`'s memos
#: (at most :data:`REPLAY_MEMO_BYTES`).
REPLAY_MEMOS = MemoBytes(REPLAY_MEMO_BYTES)


def physical_memory() -> int:
    """The machine's physical memory in bytes."""
    try:
        return os.sysconf("SC_PAGE_SIZE") * os.sysconf("SC_PHYS_PAGES")
    except (ValueError, OSError, AttributeError):  # no sysconf (Windows): assume a small machine
        return 4 * 2**30


#: Where a Linux container's memory limit is read (cgroup v2, then v1): the process's own cgroup
#: below the mount point, and the mount point itself (what a container sees as its own).
CGROUP_ROOT = Path("/sys/fs/cgroup")


def cgroup_limit(root: Path = CGROUP_ROOT, membership: str | None = None) -> int | None:
    """The memory limit of the process's cgroup in bytes (v2 ``memory.max``, v1
    ``memory.limit_in_bytes``), or None where there is none: a container killed at its limit never
    swaps first, so a budget of half the host's memory would be no budget there. ``membership``: the
    text of ``/proc/self/cgroup`` (read when None)."""
    if membership is None:
        try:
            membership = Path("/proc/self/cgroup").read_text(encoding="utf-8")
        except OSError:
            membership = ""
    own = {"v2": "/", "v1": "/"}
    for line in membership.splitlines():
        parts = line.split(":", 2)
        if len(parts) == 3 and parts[0] == "0" and parts[1] == "":
            own["v2"] = parts[2]
        elif len(parts) == 3 and "memory" in parts[1].split(","):
            own["v1"] = parts[2]
    candidates = [root / own["v2"].lstrip("/") / "memory.max", root / "memory.max",
                  root / "memory" / own["v1"].lstrip("/") / "memory.limit_in_bytes",
                  root / "memory" / "memory.limit_in_bytes"]
    limits = []
    for path in candidates:
        try:
            text = path.read_text(encoding="ascii").strip()
        except (OSError, UnicodeDecodeError):
            continue
        if text.isdigit() and int(text) < 2**60:  # "max", or v1's "no limit" (2**63 rounded to pages)
            limits.append(int(text))
    return min(limits) if limits else None


def machine_memory() -> int:
    """The memory this process may use, in bytes: the machine's physical memory, or less where a
    container's cgroup limit or the address-space limit (``ulimit -v``) says so."""
    limits = [physical_memory()]
    cgroup = cgroup_limit()
    if cgroup is not None:
        limits.append(cgroup)
    try:
        import resource  # Unix only

        soft, _ = resource.getrlimit(resource.RLIMIT_AS)
        if soft != resource.RLIM_INFINITY and soft > 0:
            limits.append(soft)
    except (ImportError, ValueError, OSError):  # no such limit on this platform
        pass
    return min(limits)


def out_of_memory(exc: MemoryError, needing: str) -> str:
    """The words for running out of the machine's memory (or ``ulimit -v``) before the budget's estimate
    stopped the work: ``needing`` is what needed it (``"answering it"``, ``"this setting"``); the work it
    belongs to is undecided, the rest stands."""
    what = f" ({exc})" if str(exc) else ""
    option = memory_option()
    if memory_option_limits():  # the option is the budget and the limit: lowering it lowers both, stopping no sooner
        return (f"out of memory{what}: {needing} needed more memory than the task's limit ({option}) before the "
                f"memory budget's estimate stopped it; {option} sets both the limit and the budget, so a lower one "
                f"would not stop it sooner: raise {option} if the machine has that much memory free")
    return (f"out of memory{what}: {needing} needed more memory than this process may use (the machine's "
            f"memory, or a limit such as `ulimit -v`) before the memory budget stopped it; a lower {option} "
            "stops the exploration within what the process has and says how far it got")


def default_max_bytes() -> int:
    """The default memory budget: :data:`DEFAULT_FRACTION` of the machine's memory (:func:`machine_memory`:
    within a container's limit and ``ulimit -v``)."""
    return int(machine_memory() * DEFAULT_FRACTION)


def parse_size(text: str) -> int:
    """``"512M"``, ``"4G"``, ``"1.5G"``, ``"64k"`` or a number of bytes; ``ValueError`` otherwise."""
    match = re.fullmatch(r"\s*(\d+(?:\.\d+)?)\s*([kKmMgGtT]?)[bB]?\s*", text)
    if match is None:
        raise ValueError(f"`{text}` is not a size: write a number of bytes or e.g. 512M, 4G, 1.5G")
    return int(Fraction(match.group(1)) * _UNITS[match.group(2).lower()])  # exact: a float loses bytes of TBs


def simulation_bytes(runs: int, samples: int, columns: int) -> int:
    """The estimated peak bytes of simulating ``runs`` runs of ``samples`` samples (sample 0 included
    besides) and evaluating ``columns`` expressions on every sample of them."""
    return runs * (samples + 1) * (RUN_BYTES_PER_SAMPLE + columns * VALUE_BYTES) * SIMULATION_PEAK_FACTOR


def learning_bytes(*, episodes: int, parallel: int, steps: int, observations: int, actions: int,
                   runs: int = 1) -> int:
    """The estimated peak bytes of ``runs`` tabular Q-learnings stepped together, each of ``episodes``
    episodes, ``parallel`` at a time, of at most ``steps`` decisions, observing ``observations`` values
    and choosing among ``actions``: the Q-table (each decision adds at most one row, the start one more:
    ``1 + episodes * steps`` rows of ``observations + actions`` float64 entries, times
    :data:`QTABLE_COPIES`, and their index), a batch's decisions kept for the replay and the episodes'
    history; and the batch's memo of the steps taken and of their replays from every location (at most
    one per decision, and all memos at most :data:`EPISODE_MEMO_BYTES` and :data:`REPLAY_MEMO_BYTES`). The
    episodes' own arrays (``parallel`` rows of the model's state) are
    small beside these."""
    rows = 1 + episodes * steps
    table = rows * ((observations + actions) * VALUE_BYTES * QTABLE_COPIES + QTABLE_INDEX_BYTES_PER_ROW
                    + observations * VALUE_BYTES)
    replay = (parallel + 1) * steps * (REPLAY_BYTES_PER_DECISION + actions)
    memo = min(EPISODE_MEMO_BYTES + REPLAY_MEMO_BYTES, runs * rows * MEMO_BYTES_PER_STEP)
    return runs * (table + replay + episodes * LEARNING_BYTES_PER_EPISODE) + memo


def evaluation_bytes(*, runs: int, steps: int, samples: int) -> int:
    """The estimated peak bytes of ``runs`` evaluation runs of learned strategies stepped together, of at
    most ``steps`` decisions over ``samples`` samples (:data:`EVALUATION_BYTES_PER_RUN`)."""
    return runs * (EVALUATION_BYTES_PER_RUN + steps * EVALUATION_BYTES_PER_STEP + samples * EVALUATION_BYTES_PER_SAMPLE)


def runs_within(max_bytes: int | None, samples: int, columns: int) -> int:
    """The most runs that :func:`simulation_bytes` allows at once within ``max_bytes`` (None: no
    limit, a very large number); 0 when not even one run fits."""
    if max_bytes is None:
        return 2**62
    return max_bytes // simulation_bytes(1, samples, columns)


class BudgetExceeded(RacError, MemoryError):
    """An exploration stopped before exceeding its budget.

    ``what`` is what was explored ("the model", "the product of model and automaton"), ``kind``
    ``"states"`` or ``"memory"``, ``limit`` the limit passed (states or bytes), ``states`` the
    states found so far, ``sample`` the sample being explored and ``seconds`` its time, and
    ``needed_bytes`` the estimated peak memory that the next step would have needed."""

    def __init__(self, *, what: str, kind: str, limit: int, states: int, sample: int, seconds: float,
                 needed_bytes: int = 0) -> None:
        self.what, self.kind, self.limit, self.states = what, kind, limit, states
        self.sample, self.seconds, self.needed_bytes = sample, seconds, needed_bytes
        when = f"by t = {seconds:g} s (sample {sample})"
        if kind == "states":
            text = f"{what} has more than {counted(limit, 'state')} {when}"
        else:
            text = (f"{what} would need about {format_bytes(needed_bytes)} {when}, more than the memory "
                    f"budget of {format_bytes(limit)} ({memory_option()}); {counted(states, 'state')} so far")
        super().__init__(text)
        #: The states the whole horizon would have at the recent growth (None: not estimated).
        self.projected_states: int | None = None

    def project(self, states: int, growth: float, horizon_sample: int) -> None:
        """Add to the message what the horizon would need at the recent ``growth`` per decision."""
        self.projected_states = states
        self.args = (f"{self.args[0]}; growing ×{growth:.3g} per decision, the horizon (sample "
                     f"{horizon_sample}) would have about {states:.2g} states",)


class EstimateExceeded(BudgetExceeded):
    """A computation refused before it starts: its estimated peak memory ``needed_bytes`` (e.g.
    :func:`learning_bytes`) exceeds the budget ``limit`` (``--max-memory``). The message names both,
    ``what`` would need it, and ``change``: what to change instead of raising the budget."""

    def __init__(self, *, what: str, needed_bytes: int, limit: int, change: str) -> None:
        option = memory_option()
        MemoryError.__init__(self, f"{what} would need about {format_bytes(needed_bytes)}, more than the memory "
                                   f"budget of {format_bytes(limit)} ({option}): {change}, or raise "
                                   f"{option} if the machine has that much memory free")
        self.what, self.kind, self.limit, self.states = what, "memory", limit, 0
        self.sample, self.seconds, self.needed_bytes = 0, 0.0, needed_bytes
        self.projected_states = None


class ProjectionExceeded(BudgetExceeded):
    """An exploration given up before its budget: at the growth seen so far, the horizon would have
    more than :data:`PROJECTION_MARGIN` times the state budget (:meth:`Budget.check_projection`).
    ``projected_states`` is that projection, ``states`` the states found so far."""

    def __init__(self, *, what: str, limit: int, states: int, sample: int, seconds: float, projected: int,
                 growth: float, horizon_sample: int) -> None:
        super().__init__(what=what, kind="states", limit=limit, states=states, sample=sample, seconds=seconds)
        self.projected_states = projected
        self.args = (f"{what} would have about {projected:.2g} states by the horizon (sample {horizon_sample}), "
                     f"growing ×{growth:.3g} per decision from {states:,} states by t = {seconds:g} s "
                     f"(sample {sample}): over {PROJECTION_MARGIN} times the budget of {limit:,} states, so it "
                     "was not explored further",)


def check_estimate(what: str, needed_bytes: int, max_bytes: int | None, change: str) -> None:
    """:class:`EstimateExceeded` when ``needed_bytes`` is more than ``max_bytes`` (None: no limit)."""
    if max_bytes is not None and needed_bytes > max_bytes:
        raise EstimateExceeded(what=what, needed_bytes=needed_bytes, limit=max_bytes, change=change)


def projected_states(layers: list[int], decide_every: int, horizon: int) -> tuple[int, float] | None:
    """The total states up to ``horizon`` if the layers went on as over the last decision (``layers[k]``:
    the states of sample ``k``), and that growth per decision; None before the first decision's
    successors are known.

    States branch only at decisions: between two decisions each state has one successor, so a layer
    keeps its size, or shrinks where states merge or are pruned. The samples after one decision are
    a *block* (the first is the successor of the decision sample, ``j * decide_every + 1``). The growth
    is the current block's states so far over the previous block's at the same samples; every later
    block is the previous block's profile (its shrinking within the block included) times that growth
    once more per decision. Before a whole previous block is known (one decision so far), the current
    layer stands for its block."""
    k = len(layers) - 1
    if k < 1:
        return None
    first = (k - 1) // decide_every * decide_every + 1  # the current block's first sample
    seen = k - first + 1
    previous = layers[first - decide_every:first] if first - decide_every >= 1 else None
    before = sum(previous[:seen]) if previous is not None else layers[0]
    if before == 0:
        return None
    growth = sum(layers[first:k + 1]) / before
    ahead = 0.0
    for sample in range(k + 1, horizon + 1):
        later, offset = divmod(sample - first, decide_every)  # blocks after the current one, place in the block
        try:
            ahead += (previous[offset] * growth ** (later + 1) if previous is not None
                      else layers[k] * growth ** later)
        except OverflowError:
            ahead = math.inf
        if ahead >= 1e18:
            break
    return int(min(sum(layers) + ahead, 1e18)), growth


@dataclass(frozen=True)
class Budget:
    """The limits of one exploration (None: no limit) and how to report exceeding them."""

    max_states: int | None = None
    max_bytes: int | None = None
    #: What is explored, for messages.
    what: str = "the model"
    #: The sample period in seconds, for messages.
    period: float = 1.0

    def check_states(self, states: int, sample: int) -> None:
        """:class:`BudgetExceeded` when ``states`` is more than :attr:`max_states`."""
        if self.max_states is not None and states > self.max_states:
            raise BudgetExceeded(what=self.what, kind="states", limit=self.max_states, states=states,
                                 sample=sample, seconds=self.seconds(sample))

    def check_bytes(self, graph_bytes: int, states: int, sample: int, working_bytes: int = 0) -> None:
        """:class:`BudgetExceeded` when deciding on a graph of ``graph_bytes`` would exceed :attr:`max_bytes`,
        or exploring it would with ``working_bytes`` more of temporary arrays."""
        needed = max(graph_bytes * PEAK_FACTOR, graph_bytes + working_bytes)
        if self.max_bytes is not None and needed > self.max_bytes:
            raise BudgetExceeded(what=self.what, kind="memory", limit=self.max_bytes, states=states,
                                 sample=sample, seconds=self.seconds(sample), needed_bytes=needed)

    def check_projection(self, layers: list[int], decide_every: int, horizon: int, sample: int,
                         horizon_sample: int) -> None:
        """:class:`ProjectionExceeded` when the states up to layer ``horizon`` at the growth seen so far
        (:func:`projected_states` of ``layers``, the states per layer so far, a decision every
        ``decide_every`` layers) are more than :data:`PROJECTION_MARGIN` times :attr:`max_states`,
        judged once two decisions and :data:`PROJECTION_FROM` of :attr:`max_states` are explored.
        ``sample`` is the last layer's sample and ``horizon_sample`` the horizon's, for the message.
        For a search that may stop short of its budget (a reference computed beside an answer, not
        the answer)."""
        if (self.max_states is None or len(layers) <= 2 * decide_every
                or sum(layers) < PROJECTION_FROM * self.max_states):
            return
        estimate = projected_states(layers, decide_every, horizon)
        if estimate is not None and estimate[0] > PROJECTION_MARGIN * self.max_states:
            raise ProjectionExceeded(what=self.what, limit=self.max_states, states=sum(layers), sample=sample,
                                     seconds=self.seconds(sample), projected=estimate[0], growth=estimate[1],
                                     horizon_sample=horizon_sample)

    def seconds(self, sample: int) -> float:
        """The time of ``sample``, rounded for messages."""
        return round(sample * self.period, 9) if math.isfinite(self.period) else float(sample)


class TimeExceeded(RacError):
    """Work given up past its time limit (:class:`TimeLimit`): ``what`` it was, the ``limit`` and the
    ``seconds`` it had run."""

    def __init__(self, *, what: str, limit: float, seconds: float) -> None:
        super().__init__(f"{what}: given up after {seconds:.3g} s, past the time limit of {limit:g} s")
        self.what, self.limit, self.seconds = what, limit, seconds


@dataclass
class TimeLimit:
    """A time limit of ``seconds`` from its creation (None: none), checked where the work can stop: between
    its steps, and as an exploration's ``progress`` (once per layer) or a simulation's (once per sample). Not
    preemptive: a step already running (Storm's decision) ends first."""

    seconds: float | None
    #: What is limited, for the message.
    what: str = "the work"
    started: float = field(default_factory=time.perf_counter)

    def remaining(self) -> float | None:
        """The seconds left (0 past the limit; None: no limit), for work with a deadline of its own."""
        if self.seconds is None:
            return None
        return max(0.0, self.seconds - (time.perf_counter() - self.started))

    def check(self, *progress: int) -> None:
        """:class:`TimeExceeded` once the limit has passed (``progress``: an exploration's arguments, unused)."""
        elapsed = time.perf_counter() - self.started
        if self.seconds is not None and elapsed > self.seconds:
            raise TimeExceeded(what=self.what, limit=self.seconds, seconds=elapsed)
