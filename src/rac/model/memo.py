"""Values computed once per key and kept: the trigonometry and trajectories of the vectorised model.

:class:`KeyedRows` maps int64 keys to rows of doubles that are a pure function of the key (the
cos/sin of a heading significand, the 1/G sub-steps of a (head, turn) pair, ...): a row is computed
the first time its key is asked for and then looked up (a sorted key array and
``np.searchsorted``, no Python loop over the rows). :mod:`rac.model.batch` uses it so that a
sample of many episodes costs a few array operations instead of one ``math.cos`` per heading and
sub-step. A row is the same doubles whenever it is computed (every computation is row by row), so
keeping it changes no result.

:func:`cos_sin` is ``math.cos``/``math.sin`` (the C library's, which the emitted C calls) over an
array, each distinct value once; numpy's own ``np.cos``/``np.sin`` may differ in the last bit.
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

__all__ = ["KeyedRows", "cos_sin", "distinct_values"]

#: A :class:`KeyedRows` keeps at most about this many doubles (16 MiB), then starts afresh.
MEMO_DOUBLES = 1 << 21
#: A :class:`KeyedRows`' new keys are merged into its main index once this many have come.
RECENT_KEYS = 4096
#: Up to this many keys are looked up one by one in a dictionary (numpy's searches cost more per call
#: than a few dictionary lookups), while the table holds at most :data:`DICT_KEYS` keys.
FEW_KEYS = 64
#: ... beyond this many kept keys the dictionary is dropped (its memory), and every lookup searches.
DICT_KEYS = 1 << 16


def cos_sin(angles: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``math.cos`` and ``math.sin`` of every element (the shape of ``angles``), called once per
    distinct bit pattern."""
    flat = np.ascontiguousarray(angles, dtype=np.float64).reshape(-1)
    bits, inverse = np.unique(flat.view(np.int64), return_inverse=True)
    values = bits.view(np.float64).tolist()
    cos = np.array([math.cos(t) for t in values], dtype=np.float64)
    sin = np.array([math.sin(t) for t in values], dtype=np.float64)
    inverse = inverse.reshape(np.shape(angles))
    return cos[inverse], sin[inverse]


#: :func:`distinct_values` marks values in a table instead of sorting them while they span at most this
#: many integers (or four times the number of values, when that is more).
_DENSE_SPAN = 1 << 16


def distinct_values(values: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """``np.unique(values, return_inverse=True)`` of a 1-d integer array (int64 results).

    When the values span few integers this marks them in a table instead of sorting (linear
    time); the result is the same: the distinct values ascending, and each element's index
    among them."""
    values = np.asarray(values, dtype=np.int64).reshape(-1)
    if values.size == 0:
        return values.copy(), np.zeros(0, dtype=np.int64)
    low = int(values.min())
    span = int(values.max()) - low + 1
    if span > max(_DENSE_SPAN, 4 * values.size):
        distinct, inverse = np.unique(values, return_inverse=True)
        return distinct, inverse.reshape(-1).astype(np.int64, copy=False)
    offset = values - low
    present = np.zeros(span, dtype=bool)
    present[offset] = True
    distinct = np.flatnonzero(present)
    rank = np.cumsum(present, dtype=np.int64)
    rank -= 1
    return distinct + low, rank[offset]


class KeyedRows:
    """``rows(keys)``: the ``(len(keys), width)`` rows of int64 keys, ``compute(distinct_keys)`` once
    per key (``compute`` must be a pure function of each key, row by row). The rows are stored in
    the order they were computed (in an array that doubles when full) and found through the sorted
    keys, so a new key costs its own row, not a copy of the table. New keys go to a small sorted
    index of their own, merged into the main one when it holds ``recent`` (:data:`RECENT_KEYS`): a few new keys at
    a time (an on-demand shield's lookahead adds them thousands of times) cost a copy of the small
    index, not of the main one. A few keys at a time (:data:`FEW_KEYS`, a sample of a few episodes) are
    looked up in a dictionary of the keys instead, while the table is small. At most about
    :data:`MEMO_DOUBLES` doubles are kept; beyond, the table starts afresh (only the time changes)."""

    def __init__(self, width: int, compute: Callable[[np.ndarray], np.ndarray], limit: int = MEMO_DOUBLES,
                 recent: int = RECENT_KEYS) -> None:
        self.width = width
        self.recent = recent
        self.compute = compute
        self.max_rows = max(1024, limit // max(1, width))
        self.keys = np.zeros(0, dtype=np.int64)  # sorted
        self.slots = np.zeros(0, dtype=np.int64)  # each sorted key's row in self.rows
        self.recent_keys = np.zeros(0, dtype=np.int64)  # sorted; none of them in self.keys
        self.recent_slots = np.zeros(0, dtype=np.int64)
        self.rows = np.zeros((64, width), dtype=np.float64)
        #: key -> its row in self.rows, for :data:`FEW_KEYS` keys at a time (None: beyond DICT_KEYS keys)
        self.slot_of: dict[int, int] | None = {}

    def __len__(self) -> int:
        return int(self.keys.size + self.recent_keys.size)

    def table(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """The rows of the distinct ``keys`` (ascending) and each key's index among them: for many
        keys with few distinct ones, cheaper than :meth:`__call__` (one lookup per distinct key)."""
        distinct, inverse = distinct_values(keys)
        return self(distinct), inverse

    def __call__(self, keys: np.ndarray) -> np.ndarray:
        keys = np.asarray(keys, dtype=np.int64)
        slot_of = self.slot_of
        if slot_of is not None and keys.ndim == 1 and keys.size <= FEW_KEYS:
            listed = keys.tolist()
            slots = [slot_of.get(key, -1) for key in listed]
            if -1 not in slots:  # all kept: the same rows as the search finds
                return self.rows[slots]
            fresh_keys = sorted({key for key, slot in zip(listed, slots) if slot < 0})  # np.unique's
            if len(self) + len(fresh_keys) <= self.max_rows:  # no fresh start: the new rows added
                fresh = np.array(fresh_keys, dtype=np.int64)
                self._add(fresh, np.asarray(self.compute(fresh), dtype=np.float64).reshape(fresh.size, self.width))
                if self.slot_of is not None:
                    return self.rows[[self.slot_of[key] for key in listed]]
                return self.rows[self._find(keys)[0]]
        slot, found = self._find(keys)
        if not found.all():
            fresh = np.unique(keys[~found])
            rows = np.asarray(self.compute(fresh), dtype=np.float64).reshape(fresh.size, self.width)
            if len(self) + fresh.size > self.max_rows:  # start afresh, with the rows asked for now
                kept_keys, first = np.unique(keys[found], return_index=True)
                kept_rows = self.rows[slot[found][first]]
                fresh = np.concatenate([kept_keys, fresh])
                rows = np.concatenate([kept_rows, rows])
                order = np.argsort(fresh)
                fresh, rows = fresh[order], rows[order]
                self.keys, self.slots = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
                self.recent_keys, self.recent_slots = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
                self.slot_of = {}
            self._add(fresh, rows)
            slot, found = self._find(keys)
        return self.rows[slot]

    def _find(self, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each key's row in :attr:`rows` (0 where it is missing) and whether the key is there."""
        slot, found = self._search(self.keys, self.slots, keys)
        if self.recent_keys.size and not found.all():
            missing = np.flatnonzero(~found.reshape(-1))
            more, there = self._search(self.recent_keys, self.recent_slots, keys.reshape(-1)[missing])
            slot.reshape(-1)[missing[there]] = more[there]
            found.reshape(-1)[missing[there]] = True
        return slot, found

    @staticmethod
    def _search(index: np.ndarray, slots: np.ndarray, keys: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Each key's slot through one sorted ``index`` (0 where it is missing) and whether it is there."""
        if index.size == 0:
            return np.zeros(keys.shape, dtype=np.int64), np.zeros(keys.shape, dtype=bool)
        position = np.searchsorted(index, keys)
        np.minimum(position, index.size - 1, out=position)
        here = index[position] == keys
        return np.where(here, slots[position], 0), here

    def _add(self, keys: np.ndarray, rows: np.ndarray) -> None:
        """Distinct ascending ``keys``, none in the table yet, and their rows."""
        count = len(self)
        need = count + keys.size
        if need > self.rows.shape[0]:
            grown = np.zeros((max(2 * self.rows.shape[0], need), self.width))
            grown[:count] = self.rows[:count]
            self.rows = grown
        self.rows[count:need] = rows
        if self.slot_of is not None:
            if need > DICT_KEYS:
                self.slot_of = None
            else:
                self.slot_of.update(zip(keys.tolist(), range(count, need)))
        where = np.searchsorted(self.recent_keys, keys)
        self.recent_keys = np.insert(self.recent_keys, where, keys)
        self.recent_slots = np.insert(self.recent_slots, where, np.arange(count, need))
        if self.recent_keys.size >= self.recent:  # one copy of the main index for many new keys
            where = np.searchsorted(self.keys, self.recent_keys)
            self.keys = np.insert(self.keys, where, self.recent_keys)
            self.slots = np.insert(self.slots, where, self.recent_slots)
            self.recent_keys, self.recent_slots = np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
