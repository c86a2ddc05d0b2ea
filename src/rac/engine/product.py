"""The product of the scenario model and the reward automaton: Qe–Qh on runs the model can produce (issue 4).

:func:`explore_product` explores, breadth-first and vectorised like :func:`rac.engine.explore.explore`,
the discrete states of the whole UPPAAL model that ``rac compile --target uppaal`` emits for a file
with a ``model`` block (:mod:`rac.targets.uppaal.model`): the ego, the automaton's location, its
inputs and the integer *mirrors* of its rewards, in exactly the emitted integer arithmetic.
:func:`decide_in_model` then decides a path query (``A[] isClose imply Unsafe``) on that graph with
Storm, so the query is answered on runs the scenario can produce, not on every input sequence
(``rac check``'s P2 lets the inputs range freely: a counterexample may need inputs no run has).

**One sample** ``k`` (1-based), in the order of the emitted Timer (``count`` becomes ``k``):

1. ``accrue!`` — the Controller runs ``sense_state()``: the ego moves over the last period with the
   current jerk and turn; every mirror grows by its location's rate times the period, read on the
   inputs held from sample ``k - 1`` (``mirror += c + p*input / q``, integer division per term). At
   the first sample, when some rate reads an input, nothing accrues here (nothing is held yet);
2. ``read!`` — the Controller assigns every input from its binding, evaluated on sample ``k``
   (numbers as the significand ``d2i(e)``, truncated towards zero; ``prev(e)`` is ``e`` at sample
   ``k - 1``, at the first sample ``e`` in the initial state), then ``prev(e) := e``. At the first
   sample, when some rate reads an input, the mirrors accrue here with these inputs;
3. ``sense!`` — the automaton takes its enabled edge, if any: updates left to right, each
   ``mirror = (Σ a*v + b) / q`` in integers (exact with whole coefficients, else truncated once);
4. ``decide!`` when ``k % decide_every == 0`` and ``k`` is before the horizon: a choice per
   (jerk, turn) pair (action index as in :func:`rac.engine.explore.action_pairs`; at time 0 too).

After the horizon's last sample ``finish!`` applies the ``at end`` clauses in order, on the inputs of
that sample. With ``episode ends when COND`` (:attr:`rac.ir.Automaton.ending`), a sample
whose inputs satisfy COND is the last of its run, as in the emitted model: its ``sampled`` state is
followed by its ``ended`` state (the ``at end`` clauses applied on its inputs; with no clauses, the
``sampled`` state itself is terminal), and nothing else. ``horizon_samples`` stands for the
automaton's ``horizon`` (the emitted model of a copy with ``horizon = horizon_samples * period``,
as docs/uppaal.md suggests for Qe–Qh; the default, the automaton's own horizon, is the emitted model
itself).

**States** are the instants at which a query can see something new (:data:`PHASES`): ``sampled``
(after the edge; the start, at ``k = 0``, is one), ``accrued`` (after ``accrue!``: the new ego and
rewards, still the last sample's location and inputs — the instant before the edge, at which a
reward peaks), ``read`` (after ``read!``; only at the first sample, when a rate reads an input, since
only then does it show other rewards than ``accrued``) and ``ended`` (after ``finish!``; only when
the automaton has ``at end`` clauses). The columns of :attr:`ProductGraph.states` are ``k, phase``,
the ego, ``location``, the inputs (booleans 0/1, numbers as significands: the emitted model's input
globals, 0 before the first reading) and the mirrors; states also differ by the values of the
bindings' ``prev(e)`` variables (:attr:`ProductGraph.prev_values`), as they do in UPPAAL. Each
layer (one sample, one phase) is merged with ``np.unique``. Not states, as in ``explore()``: the
period after a decision, in which the emitted model already shows the new jerk and turn beside
the sample's other values (here they show from the next sample on; the emitted queries that read
them leave that period out), and the delays between samples (``time`` is read at sample instants
only, as the emitted queries read it: the sample counter).

Every input needs a binding (a checked file with a ``model`` block has one for each, E0709):
:class:`ValueError` otherwise. As in the emitted model, ``assume`` and the inputs' declared bounds
are not enforced on the values the bindings give. A mirror leaving int32 (UPPAAL aborts there), or
a product or partial sum on the way to one (the emitted arithmetic is int32 throughout), raises
:class:`rac.model.ModelRangeError`.

The model's own states rarely merge (centimetre positions are unique per action history), so product
state spaces grow fast: pass ``max_states`` and ``max_bytes`` for a
clean :class:`~rac.engine.budget.BudgetExceeded` instead of running out of memory.

Example (81 action pairs every 0.2 s: 4 samples are 33,000 states, 6 samples 2.7 million)::

    result = compile_file("examples/left_turn/model.ra")
    verdict = decide_in_model(result, None, "Qh", horizon_samples=4, max_states=1_000_000)
    verdict.holds, verdict.trace
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from fractions import Fraction

import numpy as np

from rac import ir
from rac.core.diagnostics import RacValueError
from rac.core.numbers import INT32_MAX, INT32_MIN
from rac.engine.allow import ActionGuard, action_pairs
from rac.engine.bindings import Bindings
from rac.engine.budget import GRAPH_BYTES_PER_CHOICE, Budget
from rac.engine.evaluate import EvaluationError, Evaluator, Frame
from rac.engine.graph import LABELS, ExploredGraph
from rac.engine.storm import Verdict, decide
from rac.ir import expr as ie
from rac.ir import query as iq
from rac.ir.significands import Unrepresentable, common_denominator, rate_diagnostic, unrepresentable
from rac.ir.vocabulary import EGO_STATE
from rac.model.data import ModelData, ModelRangeError
from rac.model.program import CheckedProgram, ProgramSource, program_of
from rac.model.sample import ACTION, CRASHED, EGO, PRODUCT_EGO, ProductColumn, collides
from rac.model.sample import labels as label_states
from rac.runtime.semantics import first_sample_reads, mirror_accrual, mirror_update

__all__ = ["ACCRUED", "ENDED", "PHASES", "READ", "SAMPLED", "MirrorArithmetic", "ProductGraph", "decide_in_model",
           "decide_product", "explore_product", "trace_to"]

#: The ``phase`` column: which instant of its sample a state is (see the module docstring).
PHASES: tuple[str, ...] = ("accrued", "read", "sampled", "ended")
ACCRUED, READ, SAMPLED, ENDED = range(4)

Progress = Callable[[int, int, int], None]
_CALLS = {name: ie.call(name) for name in ("mindist", "offroad", "goal")}


# ---------------------------------------------------------------- integer arithmetic as UPPAAL's
def _tdiv(a: np.ndarray, q: int) -> np.ndarray:
    """C's (and UPPAAL's) integer division by ``q > 0``: truncated towards zero."""
    return a if q == 1 else np.where(a < 0, -((-a) // q), a // q)


def _int32(values: np.ndarray, what: str, scale: int) -> np.ndarray:
    """``values`` as int64 after checking that each fits the emitted ``int32_t``: ``INT32_MIN`` too, which
    a mirror may hold though no literal can write it (UPPAAL's ``int32_t`` is ``int[-2147483648, ...]``),
    as the int32 range check (E0501) and the update check (E0801) allow it."""
    bad = (values < INT32_MIN) | (values > INT32_MAX)
    if np.any(bad):
        value = int(values[np.flatnonzero(bad)[0]])
        raise ModelRangeError(what, Fraction(value, scale), value, scale, INT32_MIN)
    return values.astype(np.int64)


class MirrorArithmetic:
    """The automaton's integer side exactly as emitted: mirror accruals, guards, edges, ``at end``
    (public for the tests that compare it with the emitted C functions and the UPPAAL network)."""

    def __init__(self, automaton: ir.Automaton, scale: int) -> None:
        self.a = automaton
        self.scale = scale
        self.reward = {r: i for i, r in enumerate(automaton.rewards)}
        self.input = {item.name: i for i, item in enumerate(automaton.inputs)}
        period = Fraction(automaton.period)
        self.accruals = []  # per location, per reward: (constant, [(sign, p, q, input column)])
        for location in automaton.locations:
            row = []
            for reward, rate in zip(automaton.rewards, location.rates):
                const, terms = mirror_accrual(rate, period, scale)
                if const.denominator != 1:  # the emitted model does not exist: the checker's E0801
                    problem = rate_diagnostic(automaton, location, reward, rate) or unrepresentable(
                        automaton, f"reward rate of `{reward}` in location `{location.name}` adds {const} "
                        "significand units per sample, not a whole number", location.span)
                    raise Unrepresentable(diagnostic=problem)
                row.append((int(const), [(1 if c > 0 else -1, abs(c.numerator), c.denominator, self.input[name])
                                         for c, name in terms if c != 0]))
            self.accruals.append(row)

    # ------------------------------------------------------------ the pieces of one sample
    def accrue(self, loc: np.ndarray, inputs: np.ndarray, mirrors: np.ndarray) -> np.ndarray:
        """The mirrors after one sample's accrual in ``loc`` with ``inputs`` (the ``accrue?`` loop)."""
        out = mirrors.copy()
        for location, row in enumerate(self.accruals):
            rows = np.flatnonzero(loc == location)
            if rows.size == 0:
                continue
            for r, (const, terms) in enumerate(row):
                if const == 0 and not terms:
                    continue
                # print_exact_sum's `iR + p*x / q + ... + const`, every value on the way an int32 as in UPPAAL
                inside = f"a value inside the accrual of `{self.a.rewards[r]}`"
                total = out[rows, r].astype(np.int64)
                for sign, p, q, i in terms:
                    product = _int32(p * inputs[rows, i].astype(np.int64), inside, self.scale)
                    total = _int32(total + sign * _tdiv(product, q), inside, self.scale)
                out[rows, r] = _int32(total + const, f"the mirror of `{self.a.rewards[r]}`", self.scale)
        return out

    def guard(self, guard: ir.Guard, inputs: np.ndarray) -> np.ndarray:
        """A guard on the input globals (numbers as significands, thresholds compared exactly)."""
        n = inputs.shape[0]

        def atom(leaf: ir.BAtom) -> np.ndarray:
            bound = ie.integer_bound(leaf.op, leaf.threshold * self.scale)
            if isinstance(bound, bool):
                return np.full(n, bound)
            op, value = bound
            return _compare(inputs[:, self.input[leaf.input]], op, value)

        fold: ir.GuardFold[np.ndarray] = ir.GuardFold(
            const=lambda value: np.full(n, value),
            boolean=lambda leaf: inputs[:, self.input[leaf.name]] != 0,
            atom=atom,
            negate=lambda inner: ~inner,
            conjoin=lambda parts: np.logical_and.reduce(parts) if parts else np.full(n, True),
            disjoin=lambda parts: np.logical_or.reduce(parts) if parts else np.full(n, False))
        return fold(guard)

    def update(self, updates: Sequence[ir.Assignment], inputs: np.ndarray, mirrors: np.ndarray) -> None:
        """Apply ``updates`` left to right to ``mirrors`` in place (each reads the ones before it)."""
        n = mirrors.shape[0]
        for assignment in updates:
            const, terms = mirror_update(assignment.value, self.scale)
            q, k, ints = common_denominator(const, terms)
            if not ints:
                value = np.full(n, math.trunc(const), dtype=np.int64)
            else:  # print_int_linear's `(k1*x1 + ... + k) / q`, every value on the way an int32 as in UPPAAL
                inside = f"a value inside the update of `{assignment.reward}`"
                total = np.zeros(n, dtype=np.int64)
                for c, name in ints:
                    column = mirrors[:, self.reward[name]] if name in self.reward else inputs[:, self.input[name]]
                    total = _int32(total + _int32(c * column.astype(np.int64), inside, self.scale), inside,
                                   self.scale)
                value = _tdiv(_int32(total + k, inside, self.scale) if k else total, q)
            mirrors[:, self.reward[assignment.reward]] = _int32(
                value, f"the mirror of `{assignment.reward}`", self.scale)

    def edges(self, loc: np.ndarray, inputs: np.ndarray, mirrors: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Location and mirrors after ``sense!``: the enabled edge of each state's location, or none.

        Checked automata are deterministic under ``assume``, but the bindings may give inputs that
        ``assume`` excludes (it is not enforced, as in the emitted model). Where two edges are then
        enabled at once, the emitted model takes either and the product cannot follow it: an
        :class:`EvaluationError` says so, rather than an answer on the first edge alone."""
        before, loc, mirrors = loc, loc.copy(), mirrors.copy()
        for source, group in enumerate(self.a.edges):
            # by the location before the sample: a state that enters `source` now takes no second edge
            rows = np.flatnonzero(before == source)
            if rows.size == 0:
                continue
            taken_by = np.full(rows.size, -1)
            for e, edge in enumerate(group):
                enabled = self.guard(edge.guard, inputs[rows])
                both = enabled & (taken_by >= 0)
                if both.any():
                    first = int(np.flatnonzero(both)[0])
                    raise EvaluationError(self._nondeterministic(group[taken_by[first]], edge, inputs[rows[first]]),
                                          edge.span)
                taken_by[enabled] = e
            for e, edge in enumerate(group):
                taken = rows[taken_by == e]
                if taken.size:
                    block = mirrors[taken]
                    self.update(edge.updates, inputs[taken], block)
                    mirrors[taken] = block
                    loc[taken] = edge.target
        return loc, mirrors

    def _nondeterministic(self, first: ir.Edge, second: ir.Edge, inputs: np.ndarray) -> str:
        """Why the product stops where two edges are enabled at once, on one state's ``inputs``."""
        names = self.a.location_names
        values = ", ".join(f"{item.name} = {'true' if inputs[i] else 'false'}" if item.is_bool
                           else f"{item.name} = {int(inputs[i]) / self.scale}"
                           for i, item in enumerate(self.a.inputs))
        return (f"the edges `{names[first.source]} -> {names[first.target]}` and `{names[second.source]} -> "
                f"{names[second.target]}` are both enabled in a state the model reaches, on inputs the bindings "
                f"give ({values}) that `assume` excludes (rac check proves determinism under `assume` only): the "
                "emitted UPPAAL model may take either edge there, and rac's engine does not follow both")

    def end(self, inputs: np.ndarray, mirrors: np.ndarray) -> np.ndarray:
        """The mirrors after ``finish!``: every ``at end`` clause whose guard holds, in order."""
        mirrors = mirrors.copy()
        for clause in self.a.end_clauses:
            rows = np.flatnonzero(self.guard(clause.guard, inputs))
            if rows.size:
                block = mirrors[rows]
                self.update(clause.updates, inputs[rows], block)
                mirrors[rows] = block
        return mirrors


def _compare(values: np.ndarray, op: str, bound: int | np.ndarray) -> np.ndarray:
    return {"<": np.less, "<=": np.less_equal, ">": np.greater, ">=": np.greater_equal,
            "==": np.equal, "!=": np.not_equal}[op](values, bound)


# ---------------------------------------------------------------- bindings
# ---------------------------------------------------------------- layers
@dataclass
class _Layer:
    """The states of one sample and phase (or the rows that become them, before merging)."""

    k: int
    phase: int
    ego: np.ndarray  # (n, 7) int64
    loc: np.ndarray  # (n,) int64
    inputs: np.ndarray  # (n, inputs) int64
    mirrors: np.ndarray  # (n, rewards) int64
    prevs: np.ndarray  # (n, prevs) float64
    labels: dict[str, np.ndarray]

    @property
    def n(self) -> int:
        return int(self.loc.shape[0])

    def take(self, index: np.ndarray) -> _Layer:
        return _Layer(self.k, self.phase, self.ego[index], self.loc[index], self.inputs[index], self.mirrors[index],
                      self.prevs[index], {name: mask[index] for name, mask in self.labels.items()})

    def merged(self) -> tuple[_Layer, np.ndarray, np.ndarray]:
        """The distinct states (sorted), the row of each one's first occurrence, and each row's state."""
        if self.n == 0:
            empty = np.zeros(0, dtype=np.int64)
            return self, empty, empty
        key = np.hstack([self.ego, self.loc[:, None], self.inputs, self.mirrors,
                         np.ascontiguousarray(self.prevs).view(np.int64)])
        _, first, inverse = np.unique(key, axis=0, return_index=True, return_inverse=True)
        return self.take(first), first, inverse.reshape(-1)


class _Builder:
    """Layers in state order and the choices from each layer into the next one, within a budget."""

    def __init__(self, budget: Budget, state_bytes: int) -> None:
        self.budget = budget
        #: The bytes of one state while exploring (int64 columns, labels) and of one choice.
        self.state_bytes = state_bytes
        self.layers: list[_Layer] = []
        #: Per layer, in order: its states' choice counts, the actions, each choice's target (an index into
        #: the layer ``skip`` layers on: 1, the next one, or 2 past an early `ended` layer).
        self.links: list[tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]] = []
        self.total = self.choices = 0

    def add(self, layer: _Layer) -> None:
        self.layers.append(layer)
        self.total += layer.n
        self.budget.check_states(self.total, layer.k)

    def reserve(self, rows: int, k: int) -> None:
        """Before ``rows`` successor rows of sample ``k`` are built: room for them as states and choices."""
        self.choices += rows
        needed = (self.total + rows) * self.state_bytes + self.choices * GRAPH_BYTES_PER_CHOICE
        self.budget.check_bytes(needed, self.total, k)

    def link(self, counts: np.ndarray, actions: np.ndarray, targets: np.ndarray,
             skip: np.ndarray | None = None) -> None:
        skips = np.ones(targets.shape[0], dtype=np.int64) if skip is None else skip.astype(np.int64)
        self.links.append((counts.astype(np.int64), actions.astype(np.int64), targets.astype(np.int64), skips))

    def single(self, targets: np.ndarray) -> None:
        """One choice (action -1) per state of the last layer."""
        self.link(np.ones(targets.shape[0]), np.full(targets.shape[0], -1), targets)


# ---------------------------------------------------------------- the graph
@dataclass(frozen=True)
class ProductGraph(ExploredGraph):
    """An :class:`ExploredGraph` of the product (columns: :meth:`columns_of`), with its automaton.

    ``prev_values`` (n, len(prev_exprs)) holds the emitted model's ``prev(e)`` variables of every
    state (``prev_exprs`` are the bindings' ``e``). Labels: ``collide``, ``offroad``, ``goal``,
    ``safe`` as in :func:`rac.engine.explore.explore`.
    """

    automaton: ir.Automaton | None = None
    data: ModelData | None = None
    horizon: int = 0
    prev_exprs: tuple[ie.Expr, ...] = ()
    prev_values: np.ndarray | None = None
    evaluator: Evaluator | None = field(default=None, compare=False, repr=False)
    #: With ``stop_at``: the first state it marked (the exploration stopped after its layer), else -1.
    stopped_at: int = -1

    @staticmethod
    def columns_of(automaton: ir.Automaton) -> tuple[str, ...]:
        """``k, phase, x..turn, location``, the inputs, then ``mirror:REWARD`` per reward."""
        return ("k", "phase", *EGO_STATE, "location", *(i.name for i in automaton.inputs),
                *(f"mirror:{r}" for r in automaton.rewards))

    # ------------------------------------------------------------ columns
    @property
    def k(self) -> np.ndarray:
        return self.states[:, ProductColumn.K]

    @property
    def phase(self) -> np.ndarray:
        return self.states[:, ProductColumn.PHASE]

    @property
    def ego(self) -> np.ndarray:
        return self.states[:, PRODUCT_EGO]

    @property
    def location(self) -> np.ndarray:
        return self.states[:, ProductColumn.LOCATION]

    @property
    def inputs(self) -> dict[str, np.ndarray]:
        """Input name -> the emitted global per state (booleans 0/1, numbers as significands)."""
        assert self.automaton is not None
        return {item.name: self.states[:, ProductColumn.INPUTS + i] for i, item in enumerate(self.automaton.inputs)}

    @property
    def mirrors(self) -> dict[str, np.ndarray]:
        """Reward name -> its integer mirror per state (the reward times the scale)."""
        assert self.automaton is not None
        first = ProductColumn.INPUTS + len(self.automaton.inputs)
        return {r: self.states[:, first + i] for i, r in enumerate(self.automaton.rewards)}

    @property
    def settled(self) -> np.ndarray:
        """The emitted model's ``settled``: false while the inputs are not those the location reacted
        to — at the start, between ``accrue!`` and ``sense!`` of the first sample, and after ``read!``."""
        k, phase = self.k, self.phase
        return ~((k == 0) | (phase == READ) | ((phase == ACCRUED) & (k == 1)))

    # ------------------------------------------------------------ queries
    def frame(self, indices: np.ndarray | None = None) -> Frame:
        """What a query reads in the states ``indices`` (all by default): rewards as ``mirror / scale``,
        inputs as booleans or ``significand / scale``. No ``prev`` frame."""
        assert self.automaton is not None and self.data is not None
        rows = self.states if indices is None else self.states[np.asarray(indices)]
        scale = float(self.data.scale)
        inputs, significands = {}, {}
        for i, item in enumerate(self.automaton.inputs):
            column = rows[:, ProductColumn.INPUTS + i]
            inputs[item.name] = column != 0 if item.is_bool else column / scale
            if not item.is_bool:
                significands[item.name] = column
        first = ProductColumn.INPUTS + len(self.automaton.inputs)
        mirrors = {r: rows[:, first + i] for i, r in enumerate(self.automaton.rewards)}
        rewards = {r: column / scale for r, column in mirrors.items()}
        crashed = rows[:, self.columns.index("crashed")] != 0 if "crashed" in self.columns else None
        return Frame(k=rows[:, ProductColumn.K].astype(np.int64), ego=rows[:, PRODUCT_EGO],
                     location=rows[:, ProductColumn.LOCATION].astype(np.int64),
                     rewards=rewards, inputs=inputs, mirrors=mirrors, significands=significands, crashed=crashed)

    def evaluate(self, expr: ie.Expr, indices: np.ndarray | None = None) -> np.ndarray:
        """A state formula per state, as the emitted symbolic query computes it: comparisons of linear
        forms over rewards, numeric inputs, the ego and ``time`` exactly on the integers (mirrors,
        significands, ``k``); anything else in doubles (:class:`rac.engine.evaluate.Evaluator`)."""
        if ie.uses_prev(expr):
            raise EvaluationError("`prev()` cannot be read by a query on the product: a state keeps no "
                                  "previous sample", expr.span)
        assert self.evaluator is not None
        return np.asarray(self.evaluator.evaluate_bool(expr, self.frame(indices)), dtype=bool)

    def label(self, expr: ie.Expr, *, box: bool) -> np.ndarray:
        """The label the emitted query checks: a formula that reads an input only counts in settled
        states (``settled imply p`` under ``[]``, else ``settled && p``), as rac's UPPAAL target writes it."""
        value = self.evaluate(expr)
        if not any(r.kind is ie.RefKind.INPUT for r in ie.refs(expr)):
            return value
        return (value | ~self.settled) if box else (value & self.settled)


# ---------------------------------------------------------------- exploration
def explore_product(data: ModelData, automaton: ir.Automaton, *, horizon_samples: int | None = None,
                    prune_unsafe: bool = False, progress: Progress | None = None,
                    max_states: int | None = None, max_bytes: int | None = None,
                    stop_at: Callable[[ProductGraph], np.ndarray] | None = None,
                    beam: tuple[int, Callable[[ProductGraph], np.ndarray]] | None = None) -> ProductGraph:
    """Explore the product of the model and ``automaton`` breadth-first, one phase of a sample per layer.

    State 0 is the start (sample 0, ``sampled``, the ego's start with jerk and turn 0, the initial
    location, inputs and mirrors 0). ``horizon_samples`` defaults to the automaton's horizon in
    samples; the ``at end`` clauses apply after its last sample (see the module docstring for the
    order of one sample and the phases). With ``prune_unsafe=True``, ``sampled`` states that collide
    or are off-road are terminal (the automaton has reacted to the sample; nothing follows).
    ``progress(sample, sampled_states, total_states)`` is called once per sample. Product state
    spaces grow fast (the model's own states rarely merge: positions are unique per action history):
    :class:`~rac.engine.budget.BudgetExceeded` (a ``MemoryError``) as soon as more than ``max_states``
    states have been found, or before a sample's successors are built when deciding on the graph
    would need more than ``max_bytes``.
    :class:`ValueError` for an input without a binding.

    ``stop_at`` (on the fly): called with each new layer as a graph of its own states (no choices);
    where it marks a state, exploration stops after that layer and :attr:`ProductGraph.stopped_at`
    is the first marked state's index in the returned (partial) graph, which :func:`trace_to` leads to.

    ``beam`` (width, score): at each sample only the ``width`` sampled states of lowest score (the
    score is called with the layer as a graph of its own) are expanded; the graph is then not
    complete (:attr:`ExploredGraph.complete`), so it shows witnesses, never their absence.
    """
    horizon = automaton.steps if horizon_samples is None else horizon_samples
    if horizon < 0:
        raise ValueError(f"horizon_samples must be >= 0, not {horizon}")
    evaluator = Evaluator(data, automaton)
    model = evaluator.model
    arithmetic = MirrorArithmetic(automaton, data.scale)
    bindings = Bindings(evaluator, automaton, "the product")
    first_reads = first_sample_reads(automaton)
    pairs = action_pairs(data).astype(np.int64)
    guard = ActionGuard(data)
    n_inputs, n_rewards = len(automaton.inputs), len(automaton.rewards)
    ends = automaton.ending

    def labels(frame: Frame) -> dict[str, np.ndarray]:
        # through the evaluator, so that the bindings' mindist() etc. on this frame are reused
        collide = collides(evaluator.evaluate(_CALLS["mindist"], frame), model.native.td_d,
                           frame.crashed if data.sticky else None)  # collision sticky: or at an earlier sample
        offroad = np.asarray(evaluator.evaluate(_CALLS["offroad"], frame), dtype=bool)
        goal = np.asarray(evaluator.evaluate(_CALLS["goal"], frame), dtype=bool)
        return label_states(collide, offroad, goal)

    sticky = data.sticky
    ego0 = np.asarray([model.native.initial_state()], dtype=np.int64)
    start = Frame(np.zeros(1, dtype=np.int64), ego0, crashed=np.zeros(1, dtype=bool))
    start_labels = labels(start)
    if sticky:  # collision sticky: the layers' ego rows carry one more column, collide() so far (0/1)
        ego0 = np.column_stack([ego0, start_labels["collide"]]).astype(np.int64)
    sampled = _Layer(0, SAMPLED, ego0, np.full(1, automaton.initial, dtype=np.int64),
                     np.zeros((1, n_inputs), dtype=np.int64), np.zeros((1, n_rewards), dtype=np.int64),
                     bindings.prevs(start), start_labels)
    # while exploring a state is int64 columns (ego, location, inputs, mirrors, prevs) and 4 labels
    width = ego0.shape[1] + 1 + n_inputs + n_rewards + sampled.prevs.shape[1]
    built = _Builder(Budget(max_states, max_bytes, "the product of model and automaton", float(data.period)),
                     8 * width + 4)
    found = [-1]

    def add(layer: _Layer) -> bool:
        """Add ``layer``; whether ``stop_at`` marks one of its states (then exploration stops)."""
        offset = built.total
        built.add(layer)
        if stop_at is None or found[0] >= 0 or layer.n == 0:
            return False
        marked = np.flatnonzero(stop_at(_layer_graph(layer, automaton, data, horizon, bindings, evaluator)))
        if marked.size:
            found[0] = offset + int(marked[0])
        return found[0] >= 0

    stopped = add(sampled)
    if progress is not None:
        progress(0, 1, built.total)
    narrowed = False
    for k in range(0 if stopped else horizon):
        # ---- the choices: as explore(), one per action pair at decision samples
        expand = sampled.labels["safe"] if prune_unsafe else np.ones(sampled.n, dtype=bool)
        early: _Layer | None = None  # `episode ends when`: the ended states of the runs that end at sample k
        ending = np.zeros(sampled.n, dtype=bool)
        if ends is not None and k > 0:
            ending = expand & arithmetic.guard(ends, sampled.inputs)
            expand = expand & ~ending
            if automaton.end_clauses and ending.any():
                rows = sampled.take(np.flatnonzero(ending))
                early = dataclasses.replace(rows, phase=ENDED, mirrors=arithmetic.end(rows.inputs, rows.mirrors))
        if beam is not None and int(expand.sum()) > beam[0]:
            candidates = np.flatnonzero(expand)
            scores = np.asarray(beam[1](_layer_graph(sampled, automaton, data, horizon, bindings, evaluator)))
            expand = np.zeros(sampled.n, dtype=bool)
            expand[candidates[np.argsort(scores[candidates], kind="stable")[:beam[0]]]] = True
            narrowed = True
        sources = np.flatnonzero(expand)
        if early is not None:
            early, _, to_early = early.merged()
            if add(early) or sources.size == 0:  # stopped, or every run has ended: the ended layer is the last
                built.link(ending, np.full(to_early.size, -1), to_early)
                break
        if sources.size == 0:  # every state pruned (or ended): the last layer is terminal
            break
        if k % data.decide_every == 0:
            per = len(pairs)
            src = np.repeat(sources, per)
            action = np.tile(np.arange(per, dtype=np.int64), sources.size)
            chosen = pairs[action]
        else:
            per = 1
            src, action = sources, np.full(sources.size, -1, dtype=np.int64)
            chosen = sampled.ego[src, ACTION]
        counts = np.where(expand, per, 0)
        built.reserve(src.size, k + 1)
        # ---- sense_state() and read_inputs() once per distinct (ego, actions): they read nothing else
        # (prev(e) reads the ego of sample k), so the product costs no more model calls than explore()
        _, first_u, inv_u = np.unique(np.hstack([sampled.ego[src], chosen]), axis=0, return_index=True,
                                      return_inverse=True)
        inv_u = inv_u.reshape(-1)
        before = sampled.ego[src[first_u]]
        moved = before[:, EGO].copy()
        moved[:, ACTION] = chosen[first_u]
        after = model.sense(moved).astype(np.int64)
        crashed = before[:, CRASHED] != 0 if sticky else None
        now = Frame(np.full(after.shape[0], k + 1, dtype=np.int64), after, crashed=crashed,
                    prev=Frame(np.full(after.shape[0], k, dtype=np.int64), before[:, EGO], crashed=crashed))
        if k % data.decide_every == 0 and guard.restricts:
            # allow when: only the choices whose successor meets the condition (none: a terminal state);
            # read on the frame of the bindings and labels, so that they share its model calls
            ok = guard.allowed_in(now)[inv_u]
            src, action, inv_u = src[ok], action[ok], inv_u[ok]
            counts = np.bincount(src, minlength=sampled.n).astype(np.int64)
        read = bindings.read(now)
        prevs = bindings.prevs(now)
        sample_labels = labels(now)
        if sticky:
            after = np.column_stack([after, sample_labels["collide"]]).astype(np.int64)
        # ---- accrue!: the new ego, the mirrors grow with the held inputs (not at a first sample that reads them)
        mirrors = sampled.mirrors[src]
        if k > 0 or not first_reads:
            mirrors = arithmetic.accrue(sampled.loc[src], sampled.inputs[src], mirrors)
        rows = _Layer(k + 1, ACCRUED, after[inv_u], sampled.loc[src], sampled.inputs[src], mirrors,
                      sampled.prevs[src], {name: mask[inv_u] for name, mask in sample_labels.items()})
        accrued, first_a, to_accrued = rows.merged()
        if early is None:
            built.link(counts, action, to_accrued)
        else:  # the sampled layer's choices: one into the ended layer per ending state, the others past it
            state = np.concatenate([np.flatnonzero(ending), src])
            order = np.argsort(state, kind="stable")
            built.link(counts + ending, np.concatenate([np.full(to_early.size, -1), action])[order],
                       np.concatenate([to_early, to_accrued])[order],
                       np.concatenate([np.ones(to_early.size), np.full(to_accrued.size, 2)])[order])
            built.link(np.zeros(early.n), np.zeros(0), np.zeros(0))  # the ended states: terminal
        if add(accrued):
            break
        pending = inv_u[first_a]  # each accrued state's (ego, actions) entry: its new inputs and prevs
        current, inputs, prevs_now = accrued, read[pending], prevs[pending]
        if k == 0 and first_reads:  # read!: the first sample's accrual, with the inputs just read
            rows = dataclasses.replace(current, phase=READ, inputs=inputs, prevs=prevs_now,
                                       mirrors=arithmetic.accrue(current.loc, inputs, current.mirrors))
            current, _, to_read = rows.merged()
            built.single(to_read)
            if add(current):
                break
            inputs, prevs_now = current.inputs, current.prevs
        # ---- sense!: the edge
        loc, mirrors = arithmetic.edges(current.loc, inputs, current.mirrors)
        rows = dataclasses.replace(current, phase=SAMPLED, loc=loc, inputs=inputs, mirrors=mirrors, prevs=prevs_now)
        sampled, _, to_sampled = rows.merged()
        built.single(to_sampled)
        if add(sampled):
            break
        if progress is not None:
            progress(k + 1, sampled.n, built.total)
        if sampled.n == 0:
            break
    if automaton.end_clauses and horizon > 0 and sampled.k == horizon and sampled.n and found[0] < 0:
        expand = sampled.labels["safe"] if prune_unsafe else np.ones(sampled.n, dtype=bool)
        ending = np.flatnonzero(expand)
        rows = sampled.take(ending)
        rows = dataclasses.replace(rows, phase=ENDED, mirrors=arithmetic.end(rows.inputs, rows.mirrors))
        ended, _, to_ended = rows.merged()
        built.link(expand.astype(np.int64), np.full(ending.size, -1), to_ended)
        add(ended)
    built.link(np.zeros(built.layers[-1].n), np.zeros(0), np.zeros(0))
    graph = _assemble(built, automaton, data, horizon, bindings, evaluator)
    if found[0] >= 0 or narrowed:
        graph = dataclasses.replace(graph, stopped_at=found[0], complete=False)
    return graph


def _layer_graph(layer: _Layer, automaton: ir.Automaton, data: ModelData, horizon: int, bindings: Bindings,
                 evaluator: Evaluator) -> ProductGraph:
    """One layer's states as a graph without choices (what ``stop_at`` labels)."""
    states = _rows(layer)
    return ProductGraph(
        states=states, columns=ProductGraph.columns_of(automaton) + (("crashed",) if data.sticky else ()),
        choice_offsets=np.zeros(layer.n + 1, dtype=np.int64), choice_action=np.zeros(0, dtype=np.int64),
        choice_target=np.zeros(0, dtype=np.int64), initial=0, labels=dict(layer.labels), automaton=automaton,
        data=data, horizon=horizon, prev_exprs=tuple(bindings.prev_args), prev_values=layer.prevs,
        evaluator=evaluator)


def _rows(layer: _Layer) -> np.ndarray:
    """The state rows of a layer (the columns of :meth:`ProductGraph.columns_of`, then ``crashed``)."""
    return np.column_stack([np.full(layer.n, layer.k), np.full(layer.n, layer.phase), layer.ego[:, EGO], layer.loc,
                            layer.inputs, layer.mirrors, layer.ego[:, CRASHED:]]).astype(np.int32)


def trace_to(graph: ExploredGraph, target: int) -> list[int]:
    """State indices from the initial state to ``target`` along the graph's choices (a layered graph:
    each step goes back to some state with a choice into the current one)."""
    owner = np.repeat(np.arange(graph.n_states), np.diff(graph.choice_offsets))
    path = [target]
    while path[-1] != graph.initial:
        into = np.flatnonzero(graph.choice_target == path[-1])
        if into.size == 0:
            raise ValueError(f"state {path[-1]} has no predecessor: not reachable from the initial state")
        path.append(int(owner[into[0]]))
    return path[::-1]


def _assemble(built: _Builder, automaton: ir.Automaton, data: ModelData, horizon: int, bindings: Bindings,
              evaluator: Evaluator) -> ProductGraph:
    layers = built.layers
    sizes = np.array([layer.n for layer in layers], dtype=np.int64)
    starts = np.concatenate([[0], np.cumsum(sizes)])
    # under `collision sticky` the ego rows' last column, collide() so far, goes last (after the mirrors)
    states = np.concatenate([_rows(layer) for layer in layers])
    columns = ProductGraph.columns_of(automaton) + (("crashed",) if data.sticky else ())
    counts = np.concatenate([link[0] for link in built.links])
    offsets = np.zeros(states.shape[0] + 1, dtype=np.int64)
    np.cumsum(counts, out=offsets[1:])
    targets = np.concatenate([starts[i + link[3]] + link[2] for i, link in enumerate(built.links)])
    return ProductGraph(
        states=states, columns=columns, choice_offsets=offsets,
        choice_action=np.concatenate([link[1] for link in built.links]), choice_target=targets.astype(np.int64),
        initial=0, labels={name: np.concatenate([layer.labels[name] for layer in layers]) for name in LABELS},
        automaton=automaton, data=data, horizon=horizon, prev_exprs=tuple(bindings.prev_args),
        prev_values=np.concatenate([layer.prevs for layer in layers]), evaluator=evaluator)


# ---------------------------------------------------------------- deciding
def decide_product(graph: ProductGraph, query: iq.PathQuery | iq.QueryDecl, text: str = "") -> Verdict:
    """Decide ``query`` (``A[]``, ``E<>``, ``E[]``, ``A<>``, or a declaration of one) on an explored
    product with Storm.

    The state formula becomes the label :meth:`ProductGraph.label` (exact on mirrors and
    significands; ``settled`` for formulas that read inputs); the trace, when there is one, is a
    list of indices into ``graph.states``. The verdict names the query by its ``.ra`` text
    (``text``, or the declaration's).
    """
    if isinstance(query, iq.QueryDecl):
        text = text or query.text
    path = query.query if isinstance(query, iq.QueryDecl) else query
    if not isinstance(path, iq.PathQuery):
        raise RacValueError("only path queries (A[], E<>, E[], A<>) are decided on the product")
    query = path
    if query.under is not None:
        raise RacValueError(f"`under {query.under}`: strategies are not supported on the product")
    mask = graph.label(query.expr, box=query.quantifier in ("A[]", "E[]"))
    labelled = dataclasses.replace(graph, labels={**graph.labels, "query": mask})
    verdict = decide(labelled, query.quantifier, "query")
    return dataclasses.replace(verdict, query=text or f"{query.quantifier} ...")


def decide_in_model(source: ProgramSource | CheckedProgram | ir.Automaton, data: ModelData | None,
                    query: iq.PathQuery | iq.QueryDecl | str, *,
                    horizon_samples: int | None = None, prune_unsafe: bool = False,
                    max_states: int | None = None, max_bytes: int | None = None,
                    progress: Progress | None = None) -> Verdict:
    """Decide a path query of an automaton on its product with the scenario model.

    ``source`` is a :class:`rac.compiler.CompileResult` (a :class:`rac.model.program.ProgramSource`;
    :class:`rac.core.diagnostics.CheckError` when the file has errors), a
    :class:`rac.model.program.CheckedProgram` or an :class:`rac.ir.Automaton`; ``data`` the model's
    data (default: the program's; for an automaton, built from the ``model`` block's scenario, loaded
    as ``rac check`` loads it: :meth:`rac.model.program.CheckedProgram.of`); ``query`` a checked
    :class:`rac.ir.query.PathQuery`, a query declaration or the name of one of the automaton's
    queries. The other arguments are :func:`explore_product`'s.
    """
    if isinstance(source, ir.Automaton) and data is not None:
        automaton = source  # the caller's data: nothing to load
    else:
        program = program_of(source)
        automaton = program.automaton
        if data is None:
            if program.model_data is None:
                raise ValueError("the automaton has no `model` block: pass the model's data")
            data = program.model_data
    if isinstance(query, str):
        found = [decl for decl in automaton.queries if decl.name == query]
        if not found:
            raise KeyError(f"no query named {query!r}")
        query = found[0]
    if not isinstance(query, iq.PathQuery | iq.QueryDecl) or not isinstance(getattr(query, "query", query),
                                                                           iq.PathQuery):
        raise ValueError("only path queries (A[], E<>, E[], A<>) are decided on the product")
    graph = explore_product(data, automaton, horizon_samples=horizon_samples, prune_unsafe=prune_unsafe,
                            progress=progress, max_states=max_states, max_bytes=max_bytes)
    return decide_product(graph, query)
