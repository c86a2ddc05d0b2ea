"""What the vectorised model keeps between calls (issue 11) changes no value: rac.model.memo and the
kept trigonometry, sub-step trajectories and obstacle discs of rac.model.batch, bit for bit against
rac.model.native; and one run of the ground truth integrated on scalars as in a batch."""

from __future__ import annotations

import math

import numpy as np
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from test_explore import datasets, random_states

from rac.core.numbers import INT32_MAX
from rac.engine.evaluate import Evaluator, Frame
from rac.engine.simulate import Limits, integrate_one, integrate_truth
from rac.ir import expr as ie
from rac.model import ModelData, NativeModel, State, memo
from rac.model.batch import BatchModel
from rac.model.data import ModelRangeError
from rac.model.memo import KeyedRows, cos_sin
from rac.model.sample import Ego

DATASETS = datasets()


def bits(values: np.ndarray | list[float]) -> list[int]:
    """The doubles' bit patterns, flattened (equal lists: equal bit for bit)."""
    return np.ascontiguousarray(values, dtype=np.float64).reshape(-1).view(np.int64).tolist()


def test_cos_sin_is_the_c_librarys() -> None:
    rng = np.random.default_rng(1)
    angles = np.concatenate([rng.uniform(-20, 20, 500), [0.0, -0.0, math.pi, 1e-300], rng.uniform(-20, 20, 6)])
    angles = np.concatenate([angles, angles[:50]])  # repeated values too
    cos, sin = cos_sin(angles.reshape(2, -1))
    assert cos.shape == (2, angles.size // 2)
    assert bits(cos) == bits([math.cos(a) for a in angles]) and bits(sin) == bits([math.sin(a) for a in angles])


@pytest.mark.parametrize("name, data", DATASETS, ids=lambda value: value if isinstance(value, str) else "")
def test_kept_headings_are_the_c_librarys(name: str, data: ModelData) -> None:
    model = BatchModel(data)
    heads = np.random.default_rng(2).integers(-7 * data.scale, 7 * data.scale, 400)
    for _ in range(2):  # computed, then kept
        cos, sin = model.cos_sin(heads)
        assert bits(cos) == bits([math.cos(h / float(data.scale)) for h in heads.tolist()])
        assert bits(sin) == bits([math.sin(h / float(data.scale)) for h in heads.tolist()])


@settings(max_examples=40, deadline=None)
@given(batches=st.lists(st.lists(st.integers(-700, 700), min_size=1, max_size=12), min_size=1, max_size=12))
def test_the_last_few_heads_cos_sin_kept_answer_as_computed(batches: list[list[int]]) -> None:
    """A few heads' cos and sin are kept for the next call with the same heads (mindist() then offroad()
    of one frame): always the C library's, also when the caller's array changes afterwards."""
    data = DATASETS[0][1]
    model = BatchModel(data)
    heads = np.zeros(0, dtype=np.int64)
    for batch in batches + batches[::-1]:
        heads = np.array(batch, dtype=np.int64 if len(batch) % 2 else np.int32)
        for _ in range(2):
            cos, sin = model.cos_sin(heads)
            assert bits(cos) == bits([math.cos(h / float(data.scale)) for h in batch])
            assert bits(sin) == bits([math.sin(h / float(data.scale)) for h in batch])
            assert not cos.flags.writeable and not sin.flags.writeable
        heads += 1  # the caller's array written: the kept heads are a copy
        assert bits(model.cos_sin(heads)[0]) == bits([math.cos((h + 1) / float(data.scale)) for h in batch])


def test_keyed_rows_compute_each_key_once_and_start_afresh_when_full() -> None:
    computed: list[int] = []

    def compute(keys: np.ndarray) -> np.ndarray:
        computed.extend(keys.tolist())
        return np.stack([keys * 0.5, -keys.astype(np.float64)], axis=1)

    rows = KeyedRows(2, compute, limit=2 * 1024)  # 1024 rows at most
    keys = np.array([5, -3, 5, 2**40, -(2**62)], dtype=np.int64)
    assert rows(keys).tolist() == [[k * 0.5, -float(k)] for k in keys.tolist()]
    assert sorted(computed) == sorted(set(keys.tolist())) and len(rows) == 4
    assert rows(keys[::-1]).tolist() == [[k * 0.5, -float(k)] for k in keys[::-1].tolist()]
    assert len(computed) == 4  # nothing computed twice
    many = np.arange(3000, dtype=np.int64)
    for start in range(0, 3000, 700):  # past the limit: the table starts afresh, the answers stay
        part = np.concatenate([many[start:start + 700], keys])
        assert rows(part).tolist() == [[k * 0.5, -float(k)] for k in part.tolist()]
        assert len(rows) <= 1024 + 700


@settings(max_examples=60, deadline=None)
@given(batches=st.lists(st.lists(st.integers(-50, 50), min_size=1, max_size=30), min_size=1, max_size=25),
       recent=st.integers(1, 20))
def test_keyed_rows_answer_as_a_dict_would(batches: list[list[int]], recent: int) -> None:
    """Batches of keys, the new ones merged into the main index every ``recent``: the rows always the
    key's, each key computed once, the main and recent indexes sorted and disjoint (the table starting
    afresh is the test above's)."""
    computed: list[int] = []

    def compute(keys: np.ndarray) -> np.ndarray:
        computed.extend(keys.tolist())
        return np.stack([keys * 0.25, keys.astype(np.float64) ** 2], axis=1)

    rows = KeyedRows(2, compute, recent=recent)
    for batch in batches:
        keys = np.array(batch, dtype=np.int64)
        assert rows(keys).tolist() == [[k * 0.25, float(k) ** 2] for k in batch]
        assert (np.diff(rows.keys) > 0).all() and (np.diff(rows.recent_keys) > 0).all()
        assert not set(rows.keys.tolist()) & set(rows.recent_keys.tolist())
        assert rows.recent_keys.size < recent
    assert sorted(computed) == sorted({k for batch in batches for k in batch})


@settings(max_examples=40, deadline=None)
@given(batches=st.lists(st.lists(st.integers(-3000, 3000), min_size=1, max_size=90), min_size=1, max_size=30),
       dict_keys=st.integers(1, 200))
def test_keyed_rows_few_keys_by_the_dictionary_as_by_the_search(batches: list[list[int]], dict_keys: int) -> None:
    """Few keys are looked up in a dictionary while the table is small, the others searched; the table
    dropping the dictionary (past DICT_KEYS) and starting afresh (past its limit) change no row."""
    def compute(keys: np.ndarray) -> np.ndarray:
        return np.stack([keys * 0.25, keys.astype(np.float64) ** 2], axis=1)

    rows = KeyedRows(2, compute, limit=2 * 1024, recent=7)
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(memo, "DICT_KEYS", dict_keys)
        for batch in batches:
            keys = np.array(batch, dtype=np.int64)
            for _ in range(2):  # new keys, then kept ones (by the dictionary when there is one)
                assert rows(keys).tolist() == [[k * 0.25, float(k) ** 2] for k in batch]
            if rows.slot_of is not None:
                assert len(rows.slot_of) == len(rows) <= dict_keys
                assert all(rows.rows[slot].tolist() == [k * 0.25, float(k) ** 2] for k, slot in rows.slot_of.items())


@pytest.mark.parametrize("name, data", DATASETS, ids=lambda value: value if isinstance(value, str) else "")
def test_sense_and_mindist_stay_native_as_states_come_in_small_batches(name: str, data: ModelData) -> None:
    """New keys a few at a time (computed on Python floats), many at once (on arrays), kept ones,
    and a table that starts afresh: always the native values."""
    model = BatchModel(data)
    model._speeds.max_rows = model._headings.max_rows = 1024  # restarts too
    native = NativeModel(data)
    states, k = random_states(data, 2400, seed=len(name) + 10)
    for size in (1, 3, 8, 9, 400, 1, 1500):
        for _ in range(2):
            part, ks = states[:size], k[:size]
            sensed = model.sense(part)
            assert sensed.tolist() == [list(native.sense(State(*map(int, row)))) for row in part]
            expected = [native.mindist(State(*map(int, row)), int(j)) for row, j in zip(part, ks)]
            assert bits(model.mindist(part, ks)) == bits(expected)
            same = np.full(size, ks[0])  # one sample for every row, as an array
            assert bits(model.mindist(part, same)) == bits([native.mindist(State(*map(int, row)), int(ks[0]))
                                                            for row in part])
        states, k = np.roll(states, -size, axis=0), np.roll(k, -size)


@settings(max_examples=60, deadline=None)
@given(seed=st.integers(0, 10**6), size=st.integers(1, 60), far=st.integers(0, 3), column=st.sampled_from([0, 1, 4]))
def test_sense_of_a_few_rows_is_that_of_many(seed: int, size: int, far: int, column: int) -> None:
    """sense() of up to 256 rows (x and y moved together) gives what the path of many rows gives for the
    same rows, bit for bit, and the same error when a value leaves int32 (``far`` rows pushed to its edge)."""
    data = DATASETS[3][1]
    model = BatchModel(data)
    states, _ = random_states(data, size, seed=seed)
    states[:far, column] = INT32_MAX - data.scale // 2 * (column != 4)
    states[:far, Ego.V] = data.max_speed
    states = np.roll(states, seed % size, axis=0)
    repeat = 300 // size + 1  # each row repeated: more than 256 rows, the same first row out of range
    try:
        few = model.sense(states)
    except ModelRangeError as error:
        with pytest.raises(ModelRangeError) as many:
            model.sense(np.repeat(states, repeat, axis=0))
        assert str(many.value) == str(error)
        return
    assert few.tolist() == model.sense(np.repeat(states, repeat, axis=0))[::repeat].tolist()
    assert few.tolist() == [list(NativeModel(data).sense(State(*map(int, row)))) for row in states]


def test_the_speed_rows_on_python_floats_are_the_array_rows() -> None:
    data = DATASETS[0][1]
    model = BatchModel(data)
    rng = np.random.default_rng(3)
    triple = np.stack([rng.integers(data.min_speed - 50, data.max_speed + 50, 300),
                       rng.integers(-data.max_acc - 50, data.max_acc + 50, 300),
                       rng.choice(np.asarray(data.action("jerk").values), 300)], axis=1)
    arrays = model._speed_rows(None, triple)  # 300 rows: numpy's path
    scalars = np.array([model._speed_row(*row) for row in triple.tolist()])
    assert bits(arrays) == bits(scalars)


def test_collide_is_mindist_below_the_distance_once_per_frame() -> None:
    data = DATASETS[1][1]
    states, k = random_states(data, 500, seed=4)
    evaluator = Evaluator(data)
    frame = Frame(k=k, ego=states)
    collide = evaluator.evaluate(ie.call("collide"), frame)
    native = NativeModel(data)
    assert collide.tolist() == [native.collide(State(*map(int, row)), int(j)) for row, j in zip(states, k)]
    assert collide.any() and not collide.all()
    assert set(frame._cache) == {"collide", "mindist"}  # collide() read the frame's mindist()


def test_one_run_of_the_truth_is_integrated_as_in_a_batch() -> None:
    data = DATASETS[3][1]
    limits = Limits.of(data)
    rng = np.random.default_rng(5)
    for _ in range(300):
        truth = np.array([[rng.uniform(-50, 50)], [rng.uniform(-50, 50)],
                          [rng.choice([0.0, limits.max_speed, rng.uniform(0, limits.max_speed)])],
                          [rng.choice([limits.max_acc, -limits.max_acc, rng.uniform(-limits.max_acc, limits.max_acc)])],
                          [rng.uniform(-4, 4)]])
        jerk, turn = float(rng.choice([-2.0, 0.0, 2.0])), float(rng.choice([-0.4, 0.0, 0.4]))
        alone = integrate_one(truth, jerk, turn, data.period, 7, limits)
        # the same run twice side by side takes the arrays' path
        batch = integrate_truth(np.repeat(truth, 2, axis=1), np.array([jerk, jerk]), np.array([turn, turn]),
                                data.period, 7, limits)
        assert bits(alone[:, 0]) == bits(batch[:, 0]) == bits(batch[:, 1])
        assert bits(integrate_truth(truth, np.array([jerk]), np.array([turn]), data.period, 7, limits)) == bits(alone)


@pytest.mark.parametrize("name, data", DATASETS, ids=lambda value: value if isinstance(value, str) else "")
def test_the_heading_rows_on_python_floats_are_the_array_rows(name: str, data: ModelData) -> None:
    model = BatchModel(data)
    rng = np.random.default_rng(5)
    heads = rng.integers(-7 * data.scale, 7 * data.scale, 300)
    turns = rng.choice(np.asarray(data.action("turn").values), 300) * rng.choice([1, -1, 3], 300)
    keys = (heads.astype(np.int64) << 32) | (turns.astype(np.int64) & 0xFFFFFFFF)
    arrays = model._heading_rows(keys)  # 300 rows: numpy's path
    scalars = np.array([model._heading_row(key) for key in keys.tolist()])
    assert bits(arrays) == bits(scalars)
    assert bits(model._heading_rows(keys[:5])) == bits(scalars[:5])  # a few: on Python floats
