"""Step thousands of copies of one reward automaton at once with numpy.

Each column follows :class:`rac.runtime.interpreter.RewardAutomaton` to the bit: the same float
operations in the same order, elementwise (see :mod:`rac.runtime.interpreter` for the semantics).

With ``episode ends when COND``, an automaton whose sample's inputs satisfy COND ends its run at that
sample (its end clauses applied, their increase in that sample's reward) and :attr:`BatchRewardAutomaton.terminated`
marks it. Like an automaton ended by ``end_batch``, it refuses further steps (``RuntimeError``) until it
is reset: a vectorised loop steps the live automata and resets the finished ones, the terminated among
them, as gymnasium's vector environments do (``terminated | truncated``). ``end_batch`` on a terminated
automaton gives 0.0 and changes nothing, as ``end`` does on the scalar runtime.
"""

from __future__ import annotations

import copy
import functools
import operator
from collections.abc import Callable, Mapping, Sequence
from fractions import Fraction
from typing import Any, TypeVar

import numpy as np

from rac import ir
from rac.runtime.semantics import (
    ENDED_MESSAGE,
    AutomatonDescription,
    FloatAtom,
    FloatAtoms,
    FloatLinear,
    assume_checks,
    at_bounds,
    check_automaton,
    check_mapping,
    clip_inputs,
    column_array,
    float_atoms,
    float_linear,
    input_specs,
    key_error,
    object_column,
    range_error,
)

__all__ = ["BatchRewardAutomaton"]

_NP_OPS: dict[str, Callable[[np.ndarray, float], np.ndarray]] = {
    "<": np.less,
    "<=": np.less_equal,
    ">": np.greater,
    ">=": np.greater_equal,
    "==": np.equal,
    "!=": np.not_equal,
}

#: Table mode: locations × 2**atoms entries at most.
_TABLE_LIMIT = 1 << 16


_Term = TypeVar("_Term")


def _eval_np_linear(form: tuple[float, tuple[tuple[float, _Term], ...]], values: Callable[[_Term], np.ndarray],
                    n: int) -> np.ndarray:
    """``const + Σ coef * values(term)`` over ``n`` rows, left to right (a term: a reward's name, or its row)."""
    const, terms = form
    if not terms:
        return np.full(n, const)
    acc: Any = const
    for coef, name in terms:
        acc = acc + coef * values(name)
    return acc


def _rows(value: object, rows: int) -> np.ndarray:
    """``value`` as ``rows`` values (a scalar broadcast; broadcast_to only when needed: it is slow)."""
    array = np.asarray(value)
    return array if array.shape == (rows,) else np.broadcast_to(array, (rows,))


def _spread_inputs(inputs: Mapping[str, object], repeat: int) -> dict[str, object]:
    """Each row's inputs repeated for its ``repeat`` automata (scalars stay scalars)."""
    spread: dict[str, object] = {}
    for name, value in inputs.items():
        array = np.asarray(value)
        spread[name] = value if array.ndim == 0 else np.repeat(array, repeat)
    return spread


def _constant_truth(truth: bool, values: np.ndarray, threshold: float) -> np.ndarray:
    return np.full(np.shape(values), truth)


def _np_atom(compared: FloatAtom) -> tuple[Callable[[np.ndarray, float], np.ndarray], float]:
    """An atom as :func:`rac.runtime.semantics.float_atoms` compares it: a numpy comparison with a float,
    or a constant truth as one (a partial: a batch is copied and pickled)."""
    if isinstance(compared, bool):
        return functools.partial(_constant_truth, compared), 0.0
    return _NP_OPS[compared[0]], compared[1]


class _Guards:
    """Every distinct guard sub-expression of an automaton, evaluated once per call over all n."""

    def __init__(self, n: int, atoms: FloatAtoms) -> None:
        self._n = n
        self._atoms = atoms
        self._ids: dict[ir.Guard, int] = {}
        self.program: list[tuple[str, Any]] = []

    def _step(self, kind: str, arg: Any) -> int:
        self.program.append((kind, arg))
        return len(self.program) - 1

    def add(self, guard: ir.Guard) -> int:
        """The index of ``guard``'s value in :meth:`evaluate`'s list: its steps added, each distinct
        sub-guard once (``_ids``, the fold's memo, holds their indices)."""
        fold: ir.GuardFold[int] = ir.GuardFold(  # built per call: no closures kept on the instance
            const=lambda value: self._step("const", np.full(self._n, bool(value))),
            boolean=lambda leaf: self._step("input", leaf.name),
            atom=lambda leaf: self._step("atom", (leaf.input, *_np_atom(self._atoms(leaf)))),
            negate=lambda inner: self._step("not", inner),
            conjoin=lambda parts: self._step("and", parts),
            disjoin=lambda parts: self._step("or", parts))
        return fold(guard, self._ids)

    def resized(self, n: int) -> _Guards:
        """The same program over ``n`` rows: its constants at that length (every guard was added when the
        automaton was built; the steps and their indices are shared)."""
        twin = copy.copy(self)
        twin._n = n
        twin.program = [(kind, np.full(n, bool(arg[0])) if kind == "const" else arg) for kind, arg in self.program]
        return twin

    def evaluate(self, x: Mapping[str, np.ndarray]) -> list[np.ndarray]:
        out: list[np.ndarray] = []
        for kind, arg in self.program:
            if kind == "input":
                out.append(x[arg])
            elif kind == "atom":
                name, op, threshold = arg
                out.append(op(x[name], threshold))
            elif kind == "not":
                out.append(~out[arg])
            elif kind == "const":
                out.append(arg)
            else:
                value = out[arg[0]]
                combine = np.logical_and if kind == "and" else np.logical_or
                for other in arg[1:]:
                    value = combine(value, out[other])
                out.append(value)
        return out


def _atoms(guard: ir.Guard, out: dict[ir.Guard, int]) -> None:
    for atom in ir.guard_leaves(guard):
        out.setdefault(atom, len(out))


def _eval_atoms(guard: ir.Guard, bits: Mapping[ir.Guard, bool]) -> bool:
    """``guard`` with every leaf's truth given by ``bits`` (every leaf is there: no short cut needed)."""
    fold: ir.GuardFold[bool] = ir.GuardFold(const=bool, boolean=bits.__getitem__, atom=bits.__getitem__,
                                            negate=operator.not_, conjoin=all, disjoin=any)
    return fold(guard)


class BatchRewardAutomaton(AutomatonDescription):
    """``n`` independent copies of one reward automaton, stepped together with numpy.

    Each column follows exactly the semantics of :class:`RewardAutomaton` (the same float
    operations in the same order, elementwise), so the results are bit-identical to ``n``
    scalar interpreters. Inputs are arrays of shape ``(n,)`` (scalars broadcast).

    Edge selection is a table lookup over (location, truth values of the guard atoms) when
    that table is small (``strategy="table"``), else every distinct guard sub-expression is
    evaluated once per call over all ``n`` (``strategy="direct"``); ``"auto"`` picks.

    Example (a vectorised environment that ends and resets finished runs)::

        ra = RewardAutomaton(automaton).batch(4096)
        rewards = ra.step_batch(inputs)          # inputs: name -> array of shape (4096,)
        terminated = ra.terminated               # `episode ends when` held (end clauses applied)
        done |= terminated
        if done.any():
            rewards += ra.end_batch(inputs, mask=done & ~terminated)
            ra.reset(mask=done)
    """

    def __init__(self, automaton: ir.Automaton, n: int, *, strategy: str = "auto") -> None:
        check_automaton(automaton)
        if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 1:
            raise ValueError(f"a batch holds a whole number of automata, at least one (not {n!r})")
        if strategy not in ("auto", "table", "direct"):
            raise ValueError(f"unknown strategy {strategy!r}")
        self._ir = automaton
        self._n = int(n)
        self._specs = input_specs(automaton)
        self._names = tuple(s.name for s in self._specs)
        self._period = Fraction(automaton.period)
        self._index = {name: i for i, name in enumerate(automaton.rewards)}
        k, n_loc = len(automaton.rewards), len(automaton.locations)
        self._float_atoms = float_atoms(automaton)
        self._guards = _Guards(self._n, self._float_atoms)

        # ---- rates: constant tables, plus per-slot coefficient tables for input-dependent rates
        forms = [[float_linear(loc.rates[i].scaled(self._period), "rate") for loc in automaton.locations]
                 for i in range(k)]
        constants = [[f[0] for f in row] for row in forms]
        self._rate_table = np.array(constants, dtype=np.float64).reshape(k, n_loc)
        self._all_constant = all(not f[1] for row in forms for f in row)
        # Per reward: None (constant rates) or [(coefficient table over locations, input name)].
        # A location without that term has coefficient 0.0 there, which adds exactly nothing
        # (inputs are finite and a partial sum is never -0.0, since no constant is -0.0).
        self._rate_terms: list[list[tuple[np.ndarray, str]] | None] = []
        held: set[str] = set()
        for row in forms:
            width = max(len(f[1]) for f in row)
            if width == 0:
                self._rate_terms.append(None)
                continue
            slots: list[tuple[np.ndarray, str]] = []
            for slot in range(width):
                names = dict.fromkeys(f[1][slot][1] for f in row if len(f[1]) > slot)
                for name in names:
                    table = np.array([f[1][slot][0] if len(f[1]) > slot and f[1][slot][1] == name else 0.0
                                      for f in row])
                    slots.append((table, name))
                    held.add(name)
            self._rate_terms.append(slots)
        self._held_names = tuple(name for name in self._names if name in held)

        # ---- updates, grouped in classes of identical update lists (class 0: no updates)
        classes: dict[tuple[ir.Assignment, ...], int] = {(): 0}
        for edge in automaton.all_edges():
            classes.setdefault(edge.updates, len(classes))
        self._classes = [self._compile_updates(updates) for updates in classes]

        # ---- edge selection
        atoms: dict[ir.Guard, int] = {}
        for edge in automaton.all_edges():
            _atoms(edge.guard, atoms)
        _atoms(automaton.assume, atoms)
        table_size = n_loc << len(atoms)
        if strategy == "auto":
            strategy = "table" if len(atoms) <= 16 and table_size <= _TABLE_LIMIT else "direct"
        self.strategy = strategy
        if strategy == "table":
            self._build_tables(atoms, classes)
        else:
            self._direct = []
            for loc, group in enumerate(automaton.edges):
                if group:
                    self._direct.append((loc, [(self._guards.add(e.guard), e.target, classes[e.updates])
                                               for e in group]))
            self._assume_id = (None if automaton.assume == ir.TRUE else self._guards.add(automaton.assume))
        self._end = [(self._guards.add(c.guard), self._compile_updates(c.updates))
                     for c in automaton.end_clauses]
        self._end_assume = self._guards.add(automaton.assume)
        ends = automaton.ending
        self._ends_id = None if ends is None else self._guards.add(ends)
        # each clause on its own, to name the first one violated (the clauses of `assume` are already there)
        self._assume_checks = [(self._guards.add(check.guard), check) for check in assume_checks(automaton)]

        self._objective_form = float_linear(automaton.objective, "objective")
        #: the objective's constant and (coefficient, reward row) terms, in the form's order (read every sample)
        self._objective_rows = (self._objective_form[0],
                                tuple((coef, self._index[name]) for coef, name in self._objective_form[1]))
        zeros = np.zeros((k, 1))
        initial = _eval_np_linear(self._objective_form, lambda r: zeros[self._index[r]], 1)
        self._initial_objective = float(initial[0])

        n = self._n
        self._loc = np.full(n, automaton.initial, dtype=np.intp)
        self._R = np.zeros((k, n), dtype=np.float64)
        self._samples = np.zeros(n, dtype=np.int64)
        self._ended = np.zeros(n, dtype=bool)
        self._terminated = np.zeros(n, dtype=bool)
        self._n_ended = 0
        self._obj = np.full(n, self._initial_objective)
        self._held: dict[str, np.ndarray] = {name: np.zeros(n) for name in self._held_names}
        self._first = np.ones(n, dtype=bool)
        self._any_first = True
        #: Per numeric input, how many values the last ``step_batch``/``end_batch`` with ``clip=True`` clipped.
        self.clipped: dict[str, int] = {}

    def _compile_updates(self, updates: Sequence[ir.Assignment]) -> list[tuple[int, FloatLinear]]:
        return [(self._index[a.reward], float_linear(a.value, "update")) for a in updates]

    def _build_tables(self, atoms: dict[ir.Guard, int],
                      classes: dict[tuple[ir.Assignment, ...], int]) -> None:
        a = len(atoms)
        self._atom_list: list[tuple[str, Any, float]] = []
        for atom in atoms:  # an atom is an input or a comparison (ir.atoms_of)
            if isinstance(atom, ir.BInput):
                self._atom_list.append((atom.name, None, 0.0))
            else:
                assert isinstance(atom, ir.BAtom)
                self._atom_list.append((atom.input, *_np_atom(self._float_atoms(atom))))
        self._atom_bits = a
        self._code_dtype = np.uint8 if a <= 8 else np.uint16
        self._atom_weights = np.left_shift(1, np.arange(a)).astype(self._code_dtype)  # atom i: bit i
        combos = [{atom: bool(code >> bit & 1) for atom, bit in atoms.items()} for code in range(1 << a)]
        assume = self._ir.assume
        self._assume_table = (None if assume == ir.TRUE
                              else np.array([_eval_atoms(assume, bits) for bits in combos], dtype=bool))
        n_loc = len(self._ir.locations)
        nxt = np.empty(n_loc << a, dtype=np.intp)
        cls = np.zeros(n_loc << a, dtype=np.intp)
        for loc, group in enumerate(self._ir.edges):
            for code, bits in enumerate(combos):
                nxt[loc << a | code] = loc
                for edge in group:
                    if _eval_atoms(edge.guard, bits):
                        nxt[loc << a | code] = edge.target
                        cls[loc << a | code] = classes[edge.updates]
                        break
        self._next_table = nxt
        self._class_table = cls

    # -------------------------------------------------------- description
    @property
    def n(self) -> int:
        """Number of automata in the batch."""
        return self._n

    def __len__(self) -> int:
        return self._n

    # -------------------------------------------------------- state (copies)
    @property
    def locations(self) -> np.ndarray:
        """Current location index of each automaton (into ``ir.location_names``)."""
        return self._loc.copy()

    def location_names(self) -> list[str]:
        """Current location name of each automaton."""
        names = self._ir.location_names
        return [names[i] for i in self._loc.tolist()]

    @property
    def rewards(self) -> dict[str, np.ndarray]:
        """Reward name -> copy of its values across the batch."""
        return {name: self._R[i].copy() for i, name in enumerate(self._ir.rewards)}

    @property
    def objective(self) -> np.ndarray:
        """The objective's current value per automaton (a copy)."""
        return self._obj.copy()

    @property
    def samples(self) -> np.ndarray:
        """Samples since each automaton's last reset (a copy)."""
        return self._samples.copy()

    @property
    def time(self) -> np.ndarray:
        """``samples * period`` per automaton, in seconds (correctly rounded)."""
        return self._samples * self._period.numerator / self._period.denominator

    @property
    def ended(self) -> np.ndarray:
        """Which automata have ended their run, by ``end_batch`` or :attr:`terminated` (a copy)."""
        return self._ended.copy()

    @property
    def terminated(self) -> np.ndarray:
        """Which automata ``episode ends when COND`` ended: COND held on their last sample's inputs
        (a copy; all False without the declaration, and after a reset)."""
        return self._terminated.copy()

    # -------------------------------------------------------- running
    def _mask(self, mask: object, n: int | None = None, what: str = "mask") -> np.ndarray:
        """``mask`` as ``n`` booleans (default the batch's size): True/False or 0/1, nothing else."""
        n = self._n if n is None else n
        raw = np.asarray(mask)
        if raw.dtype.kind not in "biu" or (raw.dtype.kind in "iu" and not np.isin(raw, (0, 1)).all()):
            found = f"{raw.dtype} values" if raw.dtype.kind not in "iu" else \
                f"the value {raw[~np.isin(raw, (0, 1))].flat[0]}"
            raise ValueError(f"{what} must hold booleans (True/False or 0/1), not {found}")
        m = raw.astype(bool)
        if m.shape != (n,):
            raise ValueError(f"{what} must have shape ({n},), not {m.shape}")
        return m

    def reset(self, mask: np.ndarray | Sequence[bool] | None = None) -> None:
        """Reset every automaton, or those where ``mask`` is true."""
        if mask is None:
            self._loc = np.full(self._n, self._ir.initial, dtype=np.intp)
            self._R[:] = 0.0
            self._samples[:] = 0
            self._ended[:] = False
            self._terminated[:] = False
            self._obj[:] = self._initial_objective
            self._first[:] = True
        else:
            m = self._mask(mask)
            self._loc = self._loc.copy()
            self._loc[m] = self._ir.initial
            self._R[:, m] = 0.0
            self._samples[m] = 0
            self._ended[m] = False
            self._terminated[m] = False
            self._obj[m] = self._initial_objective
            self._first[m] = True
        self._n_ended = int(self._ended.sum())
        self._any_first = bool(self._first.any())

    def resume(self, locations: np.ndarray | Sequence[int], rewards: Mapping[str, np.ndarray] | None = None,
               held: Mapping[str, np.ndarray] | None = None) -> None:
        """Reset every automaton, then put automaton ``i`` in location ``locations[i]`` with the reward
        values ``rewards[name][i]`` (default 0): a run resumed from another state, e.g. to replay one
        sequence of inputs from every location (counterfactual experiences,
        :mod:`rac.learning.counterfactual`). ``held`` gives the inputs held from the previous sample
        (name -> values; at least the numeric inputs a rate reads), which the next sample's rates read;
        without it, they hold the next sample's own inputs, as after :meth:`reset` (a run's first sample)."""
        raw = np.asarray(locations)
        # floats or booleans cast to indices would resume from other locations than meant, silently
        if raw.shape != (self._n,) or (raw.size and (raw.dtype.kind not in "iu" or raw.min() < 0
                                                      or raw.max() >= len(self._ir.locations))):
            raise ValueError(f"locations must be {self._n} location indices in [0, {len(self._ir.locations)}), "
                             f"not {raw.dtype} values of shape {raw.shape}")
        unknown = sorted(repr(name) for name in (rewards or {}) if name not in self._index)
        if unknown:
            raise ValueError(f"unknown reward(s): {', '.join(unknown)} (the rewards are {', '.join(self._ir.rewards)})")
        missing = [name for name in self._held_names if held is not None and name not in held]
        if missing:
            raise ValueError(f"held must give the inputs the rates read: {', '.join(missing)} missing")
        loc = raw.astype(np.intp)
        self.reset()
        self._loc = loc.copy()
        for name, values in (rewards or {}).items():
            self._R[self._index[name]] = np.broadcast_to(np.asarray(values, dtype=np.float64), (self._n,))
        self._obj = np.array(self._objective_now(), dtype=np.float64).reshape(self._n)
        if held is not None:
            for name in self._held_names:
                self._held[name] = np.broadcast_to(np.asarray(held[name], dtype=np.float64), (self._n,)).copy()
            self._first[:] = False  # a resumed run's next sample is not its first: its rates read `held`
            self._any_first = False

    def _read(self, inputs: Mapping[str, object], rows: np.ndarray | None,
              n: int | None = None) -> dict[str, np.ndarray]:
        """Validated inputs as arrays (bool / float64) of ``n`` values (default the batch's); only ``rows``
        are checked when given."""
        n = self._n if n is None else n
        check_mapping(inputs)
        if len(inputs) != len(self._names) or any(name not in inputs for name in self._names):
            raise key_error(inputs, self._names)
        out: dict[str, np.ndarray] = {}
        for spec in self._specs:
            raw = column_array(inputs[spec.name])
            if raw.shape != (n,):
                if raw.ndim != 0:
                    raise ValueError(f"input {spec.name!r} must have shape ({n},), not {raw.shape}")
                raw = np.broadcast_to(raw, (n,))
            kind = raw.dtype.kind
            if kind == "O":  # Python objects: each row read by the scalar runtime's rule
                column = object_column(spec, raw, rows)
                if spec.is_bool:
                    out[spec.name] = column
                    continue
                value = column
            elif spec.is_bool:
                if kind not in "biu":
                    raise ValueError(f"input {spec.name!r} must hold booleans (True/False or 0/1), not {raw.dtype} "
                                     "values")
                if kind in "iu":  # 0/1, on the rows read only: an unmasked row's value is not read
                    wrong = ~np.isin(raw, (0, 1)) if rows is None else ~np.isin(raw, (0, 1)) & rows
                    if wrong.any():
                        row = int(np.flatnonzero(wrong)[0])
                        raise ValueError(f"input {spec.name!r}[{row}] = {raw[row].item()!r} is not a boolean "
                                         "(True or False)")
                out[spec.name] = raw.astype(bool, copy=False)
                continue
            elif kind not in "biuf":  # not strings or complex numbers
                raise ValueError(f"input {spec.name!r} must hold real numbers, not {raw.dtype} values")
            else:  # a float32 at a bound rounded to float32 is that bound
                value = at_bounds(spec, raw)
            if spec.bounded:
                ok = (value >= spec.low) & (value <= spec.high)
            else:
                ok = np.isfinite(value) & (value >= spec.low) & (value <= spec.high)
            if spec.kind == "int":
                ok &= np.floor(value) == value
            if rows is not None:
                ok |= ~rows
            if not ok.all():
                bad = int(np.flatnonzero(~ok)[0])
                raise range_error(spec, float(value[bad]), f"[{bad}]")
            out[spec.name] = value
        return out

    def _assume_failed(self, ok: np.ndarray, x: Mapping[str, np.ndarray]) -> ValueError:
        """The scalar runtime's error for the first automaton whose inputs violate ``assume`` (its first
        clause violated), followed by the automata that violate it (the first ten)."""
        bad = np.flatnonzero(~ok)
        first = int(bad[0])
        g = self._guards.evaluate(x)
        check = next(check for gid, check in self._assume_checks if not g[gid][first])
        error = check.error({name: x[name][first] for name, _ in check.reads})
        return ValueError(f"{error} (automata {bad[:10].tolist()}{'...' if len(bad) > 10 else ''})")

    def _apply(self, updates: list[tuple[int, FloatLinear]], where: np.ndarray,
               x: Mapping[str, np.ndarray]) -> None:
        R, index = self._R, self._index

        def value(name: str) -> np.ndarray:
            i = index.get(name)
            return R[i] if i is not None else x[name]

        for i, form in updates:
            np.copyto(R[i], _eval_np_linear(form, value, self._n), where=where)

    def _objective_now(self) -> np.ndarray:
        # the objective's form with the reward rows looked up once (read every sample)
        return _eval_np_linear(self._objective_rows, self._R.__getitem__, self._n)

    def _clip(self, inputs: Mapping[str, object], clip: bool,
              rows: np.ndarray | None) -> tuple[Mapping[str, object], dict[str, int] | None]:
        """The inputs clipped (with ``clip``) and the counts, which the caller keeps in :attr:`clipped`
        once the inputs are read: a call that raises leaves the automata untouched, the counts too."""
        if not clip:
            return inputs, None
        return clip_inputs(self._specs, inputs, rows)  # which refuses what is no mapping

    def _atom_code(self, x: Mapping[str, np.ndarray], n: int) -> np.ndarray:
        """Each row's guard atoms as the bits of one integer: the index into the edge tables."""
        # Σ atom_i << i as one product with the weights 2**i: integers, exact (no sum exceeds the dtype)
        bits = np.empty((len(self._atom_list), n), dtype=self._code_dtype)
        for i, (name, op, threshold) in enumerate(self._atom_list):
            bits[i] = x[name] if op is None else op(x[name], threshold)  # 0 or 1
        return self._atom_weights @ bits

    def _advance(self, nxt: np.ndarray, loc: np.ndarray, only: np.ndarray | None) -> np.ndarray:
        """The end of a sample (after the accrual and the edges' updates): the next locations, the
        sample count and the objective's increase, on the automata ``only`` (all when None)."""
        self._loc = nxt if only is None else np.where(only, nxt, loc)
        self._samples += 1 if only is None else only
        objective = self._objective_now()
        reward = objective - self._obj
        if only is not None:
            reward = np.where(only, reward, 0.0)
            objective = np.where(only, objective, self._obj)
        self._obj = objective
        return reward

    def step_batch(self, inputs: Mapping[str, object],
                   mask: np.ndarray | Sequence[bool] | None = None, *, clip: bool = False) -> np.ndarray:
        """One sample for every automaton, or for those where ``mask`` is true; returns each one's
        objective increase (float64, (n,); 0.0 where unmasked).

        As in :meth:`end_batch`, inputs are validated on the masked automata only, and the
        unmasked ones keep their state (they may have ended). ``clip``: numeric values outside their
        range are clipped first on the masked automata (NaN refused), :attr:`clipped` counts them per input.
        With ``episode ends when``, the automata whose inputs satisfy the condition end their run at this
        sample (end clauses applied, their increase in the reward): :attr:`terminated` marks them."""
        only = None if mask is None else self._mask(mask)
        inputs, counts = self._clip(inputs, clip, only)
        ended = self._ended if only is None else self._ended & only
        if self._n_ended and ended.any():
            raise RuntimeError(f"{ENDED_MESSAGE} (automata {np.flatnonzero(ended)[:10].tolist()} have ended)")
        x = self._read(inputs, only)
        if counts is not None:
            self.clipped = counts
        loc = self._loc
        with np.errstate(all="ignore"):
            # ---- choose edges (before anything changes: an assume violation leaves the state alone)
            fired: list[tuple[int, np.ndarray]] = []
            if self.strategy == "table":
                code = self._atom_code(x, self._n)
                if self._assume_table is not None:
                    ok = self._assume_table[code] if only is None else self._assume_table[code] | ~only
                    if not ok.all():
                        raise self._assume_failed(ok, x)
                idx = (loc << self._atom_bits) | code
                nxt = self._next_table[idx]
                if len(self._classes) > 1:
                    cls = self._class_table[idx]
                    for c in range(1, len(self._classes)):
                        m = cls == c
                        if m.any():
                            fired.append((c, m))
            else:
                g = self._guards.evaluate(x)
                if self._assume_id is not None:
                    ok = g[self._assume_id] if only is None else g[self._assume_id] | ~only
                    if not ok.all():
                        raise self._assume_failed(ok, x)
                nxt = loc.copy()
                masks: dict[int, np.ndarray] = {}
                for source, edges in self._direct:
                    rest = loc == source
                    last = len(edges) - 1
                    for j, (gid, target, c) in enumerate(edges):
                        f = rest & g[gid]
                        if j < last:
                            rest &= ~g[gid]
                        if target != source:
                            np.copyto(nxt, target, where=f)
                        if c:
                            masks[c] = masks[c] | f if c in masks else f
                fired = [(c, m) for c, m in sorted(masks.items()) if m.any()]

            # ---- accrual with the held inputs
            if self._held_names:
                held = self._held
                if self._any_first:
                    first = self._first if only is None else self._first & only
                    for name in self._held_names:
                        held[name] = np.where(first, x[name], held[name])
                    self._first &= ~first
                    self._any_first = bool(self._first.any())
            if self._all_constant:
                gain = self._rate_table[:, loc]
                self._R += gain if only is None else gain * only
            else:
                for i, terms in enumerate(self._rate_terms):
                    rate = self._rate_table[i][loc]
                    if terms is not None:
                        for table, name in terms:
                            rate = rate + table[loc] * held[name]
                    if only is None:
                        self._R[i] += rate
                    else:
                        np.add(self._R[i], rate, out=self._R[i], where=only)
            for name in self._held_names:
                value = np.array(x[name], dtype=np.float64)
                held[name] = value if only is None else np.where(only, value, held[name])

            # ---- edges
            for c, f in fired:
                self._apply(self._classes[c], f if only is None else f & only, x)
            if self._ends_id is not None:
                self._end_where(x, only)
            return self._advance(nxt, loc, only)

    def _end_where(self, x: Mapping[str, np.ndarray], only: np.ndarray | None) -> None:
        """``episode ends when``: the automata (of ``only``) whose inputs satisfy the condition end here,
        their end clauses applied with these inputs (before the objective is read)."""
        assert self._ends_id is not None
        g = self._guards.evaluate(x)
        term = g[self._ends_id] if only is None else g[self._ends_id] & only
        if not term.any():
            return
        for gid, updates in self._end:
            f = term & g[gid]
            if f.any():
                self._apply(updates, f, x)
        self._ended |= term
        self._terminated |= term
        self._n_ended = int(self._ended.sum())

    def run_samples(self, samples: Sequence[tuple[Mapping[str, object], np.ndarray, np.ndarray]], *,
                    repeat: int = 1) -> np.ndarray:
        """Several samples in a row, each ``(inputs, active, ending)`` over ``n // repeat`` rows: row ``i``
        stands for the ``repeat`` consecutive automata ``i * repeat ...`` (one real transition replayed
        from every location: :mod:`rac.learning.counterfactual`). A sample steps the ``active`` automata
        (:meth:`step_batch`) and then ends the ``ending`` ones (:meth:`end_batch`, same inputs). Returns
        each automaton's summed objective increase. An automaton that ``episode ends when`` terminated
        takes no later sample (it is left out of ``active``; ``ending`` gives it nothing).

        Bit for bit what those calls on the repeated inputs give. For an automaton whose edges are a
        table and whose rates are constants, a sample is a few array operations: inputs are read and
        the guard atoms coded on the rows, not on every copy, which makes replaying a transition cheap."""
        if isinstance(repeat, bool) or not isinstance(repeat, (int, np.integer)) or repeat < 1 or self._n % repeat:
            raise ValueError(f"repeat must be a whole number >= 1 dividing n = {self._n}, not {repeat!r}")
        repeat = int(repeat)
        rows = self._n // repeat
        total = np.zeros(self._n)
        active = np.zeros((len(samples), rows), dtype=bool)
        ending = np.zeros((len(samples), rows), dtype=bool)
        for j, (_, active_rows, ending_rows) in enumerate(samples):
            # as step_batch's masks: a float 0.5 is no boolean (a bool array's assignment made it True)
            active[j] = self._mask(active_rows, rows, "active")
            ending[j] = self._mask(ending_rows, rows, "ending")
        with np.errstate(all="ignore"):
            if not self._run_lean(samples, active, ending, repeat, total):
                for (inputs, _, _), a, e in zip(samples, active, ending, strict=True):
                    live = np.repeat(a, repeat) & ~self._terminated
                    if live.any():
                        total += self.step_batch(_spread_inputs(inputs, repeat), mask=live)
                    if e.any():
                        total += self.end_batch(_spread_inputs(inputs, repeat), mask=np.repeat(e, repeat))
        return total

    def _run_lean(self, samples: Sequence[tuple[Mapping[str, object], np.ndarray, np.ndarray]], active: np.ndarray,
                  ending: np.ndarray, repeat: int, total: np.ndarray) -> bool:
        """:meth:`run_samples` for table edges and constant rates: the inputs of all samples read and
        coded at once on the rows, then per sample the same float operations as :meth:`step_batch`, in
        the same order. False (nothing done) where it does not apply or an input is refused: the
        caller then steps sample by sample, and those calls raise the usual errors."""
        names = set(self._names)
        if (self.strategy != "table" or not self._all_constant or self._held_names or self._n_ended
                or self._ends_id is not None
                or not samples or any(not isinstance(inputs, Mapping) or set(inputs) != names
                                      for inputs, _, _ in samples)):
            return False
        ended_before = np.zeros_like(ending)
        ended_before[1:] = np.logical_or.accumulate(ending, axis=0)[:-1]
        if (active & ended_before).any() or (ending & ended_before).any():
            return False
        n_samples, rows = active.shape
        stacked = {name: np.concatenate([_rows(inputs[name], rows) for inputs, _, _ in samples])
                   for name in self._names}
        try:
            x = self._read(stacked, active.reshape(-1), n_samples * rows)
        except ValueError:
            return False
        code = self._atom_code(x, n_samples * rows).reshape(n_samples, rows)
        if self._assume_table is not None and not (self._assume_table[code] | ~active).all():
            return False
        n_classes, bits = len(self._classes), self._atom_bits
        # what the samples read, spread over the automata at once (the values np.repeat gives per sample)
        codes = np.repeat(code.astype(np.intp), repeat, axis=1)
        masks = np.repeat(active, repeat, axis=1)
        updated = {name for c in range(1, n_classes) for _, (_, terms) in self._classes[c] for _, name in terms
                   if name in x}  # the inputs an update reads (the rewards it reads are the batch's)
        spread = {name: np.repeat(x[name].reshape(n_samples, rows), repeat, axis=1) for name in updated}
        any_active: Any = active.any(axis=1).tolist()  # per sample (lists: cheaper to read one by one)
        all_active: Any = active.all(axis=1).tolist()
        any_ending: Any = ending.any(axis=1).tolist()
        for j in range(n_samples):
            if any_active[j]:
                only = None if all_active[j] else masks[j]
                loc = self._loc
                idx = (loc << bits) | codes[j]
                nxt = self._next_table[idx]
                gain = self._rate_table[:, loc]  # accrual, then the edges' updates, as step_batch
                self._R += gain if only is None else gain * only
                if n_classes > 1:
                    cls = self._class_table[idx]
                    for c in range(1, n_classes):
                        fired = cls == c if only is None else (cls == c) & only
                        if fired.any():
                            self._apply(self._classes[c], fired, {name: values[j] for name, values in spread.items()})
                total += self._advance(nxt, loc, only)
            if any_ending[j]:
                total += self.end_batch(_spread_inputs(samples[j][0], repeat), mask=np.repeat(ending[j], repeat))
        return True

    def end_batch(self, inputs: Mapping[str, object],
                  mask: np.ndarray | Sequence[bool] | None = None, *, clip: bool = False) -> np.ndarray:
        """End the runs where ``mask`` is true (all when ``None``); returns their objective increase.

        Inputs are validated on the masked automata only; unmasked ones get reward 0.0. ``clip`` as
        in :meth:`step_batch`. A :attr:`terminated` automaton gets 0.0 and is left as it is (its run
        ended at its last sample, end clauses applied), whether masked or not.
        """
        m = np.ones(self._n, dtype=bool) if mask is None else self._mask(mask)
        m &= ~self._terminated
        inputs, counts = self._clip(inputs, clip, m)
        if (self._ended & m).any():
            raise RuntimeError(f"{ENDED_MESSAGE} (automata {np.flatnonzero(self._ended & m)[:10].tolist()})")
        x = self._read(inputs, m)
        if counts is not None:
            self.clipped = counts
        with np.errstate(all="ignore"):
            g = self._guards.evaluate(x)
            ok = g[self._end_assume] | ~m
            if not ok.all():
                raise self._assume_failed(ok, x)
            for gid, updates in self._end:
                f = m & g[gid]
                if f.any():
                    self._apply(updates, f, x)
            objective = self._objective_now()
            reward = np.where(m, objective - self._obj, 0.0)
        np.copyto(self._obj, objective, where=m)
        self._ended |= m
        self._n_ended = int(self._ended.sum())
        return reward

    def __copy__(self) -> BatchRewardAutomaton:
        """A copy with run arrays of its own (locations, rewards, counters, held inputs, clip counts).

        The tables built from the IR are shared: nothing writes to them after ``__init__``.
        """
        twin = object.__new__(type(self))
        twin.__dict__.update(self.__dict__)
        for key in ("_loc", "_R", "_samples", "_ended", "_terminated", "_obj", "_first"):
            setattr(twin, key, getattr(self, key).copy())
        twin._held = {name: value.copy() for name, value in self._held.items()}
        twin.clipped = dict(self.clipped)
        return twin

    def take(self, rows: np.ndarray | Sequence[int]) -> BatchRewardAutomaton:
        """A new batch of ``len(rows)`` automata, each a copy of row ``rows[i]`` of this one (a row may
        repeat): every automaton's state goes on from there as its row's would. For exhaustive searches
        that branch every run over its choices (:mod:`rac.learning.optimum`)."""
        raw = np.asarray(rows)
        if raw.size == 0:
            raise ValueError("a batch holds at least one automaton: take() needs rows")
        # a boolean mask or floats cast to indices would copy other rows than meant, silently
        if raw.dtype.kind not in "iu" or raw.ndim != 1 or raw.min() < 0 or raw.max() >= self._n:
            raise ValueError(f"rows must be a sequence of row indices in [0, {self._n}) (not a mask), not "
                             f"{raw.dtype} values of shape {raw.shape}: {raw.reshape(-1).tolist()[:10]}")
        where = raw.astype(np.intp)
        # this batch's tables and compiled updates, shared (never changed once built: as __copy__ shares
        # them), not built again for every take (3 ms each: an exhaustive search or a lookahead takes often)
        twin = object.__new__(type(self))
        twin.__dict__.update(self.__dict__)
        twin._n = int(where.size)
        twin._guards = self._guards.resized(twin._n)
        twin.clipped = {}
        twin._loc = self._loc[where].copy()
        twin._R = self._R[:, where].copy()
        twin._samples = self._samples[where].copy()
        twin._ended = self._ended[where].copy()
        twin._terminated = self._terminated[where].copy()
        twin._obj = self._obj[where].copy()
        twin._first = self._first[where].copy()
        twin._held = {name: value[where].copy() for name, value in self._held.items()}
        twin._n_ended = int(twin._ended.sum())
        twin._any_first = bool(twin._first.any())
        return twin

    def __deepcopy__(self, memo: dict[int, object]) -> BatchRewardAutomaton:
        """As :meth:`__copy__`: the IR and the tables are never changed, so they may be shared."""
        return self.__copy__()

    def __repr__(self) -> str:
        return f"<BatchRewardAutomaton {self.name} n={self._n} strategy={self.strategy}>"
