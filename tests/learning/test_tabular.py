"""The learner's fast paths against their plain forms, to the last bit: a step's update worked out once
and applied again (the backward replay), the table's key lookups, the observation key's bytes and the
uniform choice among the allowed actions (the same random numbers drawn)."""

from __future__ import annotations

import numpy as np
from hypothesis import given, settings
from hypothesis import strategies as st
from watkins import in_order_update

from rac.learning.strategy import key_bytes, uniform_allowed
from rac.learning.tabular import UNTRIED, QTable, Transition, apply, prepare, update

#: Table values that tell the arithmetic's paths apart: both zeros, the untried value, fractions.
VALUES = st.sampled_from([UNTRIED, -3.0, 0.5, 12.25, 0.0, -0.0, 1e-17, -7.3])


@st.composite
def transitions(draw: st.DrawFn, n_rows: int, n_actions: int) -> Transition:
    n = draw(st.integers(0, 14))
    ints = st.integers(0, n_rows - 1)
    rows = np.array(draw(st.lists(ints, min_size=n, max_size=n)), dtype=np.int64)
    next_rows = np.array(draw(st.lists(ints, min_size=n, max_size=n)), dtype=np.int64)
    actions = np.array(draw(st.lists(st.integers(0, n_actions - 1), min_size=n, max_size=n)), dtype=np.int64)
    reward = np.array(draw(st.lists(st.one_of(st.floats(-50, 50), st.sampled_from([0.0, -0.0])),
                                    min_size=n, max_size=n)), dtype=np.float64)
    masks = np.array(draw(st.lists(st.lists(st.booleans(), min_size=n_actions, max_size=n_actions).filter(any),
                                   min_size=n, max_size=n)), dtype=bool).reshape(n, n_actions)
    ends = np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool)
    active = np.flatnonzero(np.array(draw(st.lists(st.booleans(), min_size=n, max_size=n)), dtype=bool))
    return Transition(active, rows, actions, reward, next_rows, masks, ends)


@settings(max_examples=400, deadline=None)
@given(st.data())
def test_a_prepared_step_applied_again_is_the_one_at_a_time_update(data: st.DataObject) -> None:
    """A batch's steps updated, then replayed backwards from their prepared form (as the learner does),
    leave the table exactly as the oracle does, whether entries repeat within a step (few rows and
    actions) or a next row is a row the step updates (the loop)."""
    n_rows, n_actions = data.draw(st.integers(1, 6)), data.draw(st.integers(1, 4))
    steps = data.draw(st.lists(transitions(n_rows, n_actions), min_size=1, max_size=4))
    alpha = data.draw(st.sampled_from([1.0, 0.3]))
    gamma = data.draw(st.sampled_from([1.0, 0.9, 0.0]))
    untried = data.draw(st.sampled_from([UNTRIED, None]))
    start = np.array(data.draw(st.lists(VALUES, min_size=n_rows * n_actions, max_size=n_rows * n_actions)))
    start = start.reshape(n_rows, n_actions)
    expected, got, again = start.copy(), start.copy(), start.copy()
    prepared = []
    for step in steps:
        in_order_update(expected, step, alpha, gamma, untried)
        prepared.append(prepare(step, n_actions))
        apply(got, prepared[-1], alpha, gamma, untried)
    for step, plan in zip(reversed(steps), reversed(prepared)):
        in_order_update(expected, step, alpha, gamma, untried)
        apply(got, plan, alpha, gamma, untried)
    # bit for bit: NaN (0 * -inf never comes: every mask allows an action) and the sign of zero included
    assert expected.tobytes() == got.tobytes()
    for step in steps:
        update(again, step, alpha, gamma, untried)
    for step in reversed(steps):
        update(again, step, alpha, gamma, untried)
    assert again.tobytes() == expected.tobytes()


@settings(max_examples=200, deadline=None)
@given(st.data())
def test_the_table_finds_and_adds_keys_as_one_key_at_a_time(data: st.DataObject) -> None:
    width = data.draw(st.integers(0, 3))
    cell = st.sampled_from([0.0, -0.0, 1.0, 2.5, -4.0])
    table, plain = QTable(width, 2, initial=UNTRIED), {}
    for _ in range(data.draw(st.integers(1, 5))):
        n = data.draw(st.integers(0, 8))
        keys = np.array(data.draw(st.lists(st.lists(cell, min_size=width, max_size=width), min_size=n, max_size=n)),
                        dtype=np.float64).reshape(n, width)
        create = data.draw(st.booleans())
        expected = []
        for key in keys:
            raw = key.tobytes()
            if raw not in plain and create:
                plain[raw] = len(plain)
            expected.append(plain.get(raw, -1))
        rows = table.rows(keys, create=create)
        assert rows.dtype == np.int64 and rows.tolist() == expected
        assert table.size == len(plain)
        for raw, row in plain.items():
            assert table.keys[row].tobytes() == raw and (table.values[row] == UNTRIED).all()


@given(st.integers(0, 20), st.integers(0, 4))
def test_key_bytes_are_each_rows_bytes(n: int, width: int) -> None:
    ints = np.random.default_rng(n).integers(-3, 3, size=(n, width))
    keys = ints.astype(np.float64)
    keys[ints == 0] = -0.0  # the bytes tell the zeros apart; observation_keys makes every zero +0.0
    assert key_bytes(keys) == [row.tobytes() for row in keys]
    assert key_bytes(np.asfortranarray(keys)) == [row.tobytes() for row in keys]  # not C-contiguous
    assert key_bytes(ints) == [row.astype(np.float64).tobytes() for row in ints]


@settings(max_examples=100, deadline=None)
@given(st.integers(0, 2**32), st.integers(0, 20), st.integers(1, 9), st.sampled_from([0.5, 1.0]))
def test_uniform_allowed_draws_as_before(seed: int, n: int, n_actions: int, allowed: float) -> None:
    """The choice and the random numbers drawn are those of the plain form (``sum``, ``cumsum``, ``argmax``),
    every action allowed (``allowed`` 1) or some."""
    masks = np.random.default_rng(seed + 1).random((n, n_actions)) < allowed
    masks[np.arange(n), np.random.default_rng(seed + 2).integers(0, n_actions, size=n)] = True
    rng, plain = np.random.default_rng(seed), np.random.default_rng(seed)
    got = uniform_allowed(rng, masks)
    pick = plain.integers(0, masks.sum(axis=1))
    expected = np.argmax(np.cumsum(masks, axis=1) > pick[:, None], axis=1).astype(np.int64)
    assert got.dtype == np.int64 and np.array_equal(got, expected)
    assert masks[np.arange(n), got].all()
    assert rng.random() == plain.random()  # the same draws: the streams stay together
