"""The safety shield state by state where the model is too large to explore (rac.engine.ondemand).

The oracle is the exhaustive shield (the table over the whole explored model, Storm's own): on tiny
scenes, forcing the on-demand shield with a state budget the model exceeds, Qd's verdict is the
table's, every action the on-demand shield allows the table allows too (it is sound), and the
queries under it are answered (simulations and learning) where the table's would be.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from engine_files import QUERIES, write_engine_file

from rac.compiler import compile_file
from rac.engine import ondemand
from rac.engine import shield as shields
from rac.engine.lookahead import Lookahead
from rac.engine.ondemand import on_demand
from rac.engine.simulate import simulate
from rac.verify.context import VerifyOptions
from rac.verify.runner import run_queries

UNDER = {"safe": QUERIES["safe"], "Shielded": QUERIES["Shielded"], "Prob": "Pr[<=2](<> collide()) under safe",
         "Learn": QUERIES["Learn"]}


@pytest.mark.parametrize("scene", ["avoidable_obstacle", "goal_behind_wall", "goal_ahead"])
def test_the_on_demand_shield_allows_only_what_the_table_allows(tmp_path: Path, scene: str) -> None:
    path = write_engine_file(tmp_path, scene, {"safe": QUERIES["safe"]})
    result = compile_file(path)
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    computed, table = shields.synthesise(data, horizon)
    lazy = on_demand(data, horizon, seconds=None, nodes=None)  # unbounded: exactly the table's masks
    budgeted = on_demand(data, horizon)  # fixed continuations tried first, then a budgeted search
    runs = simulate(data, runs=30, horizon_samples=horizon, seed=3, policy=table.masks_at)
    for k in range(0, horizon, data.decide_every):
        rows = np.column_stack([np.full(runs.states.shape[0], k), runs.states[:, k, :7]]).astype(np.int32)
        exhaustive, found, quick = table.masks_for(rows), lazy.masks_for(rows), budgeted.masks_for(rows)
        assert not (found & ~exhaustive).any(), (scene, k)  # sound
        assert (found == exhaustive).all(), (scene, k)  # and, unbounded, as permissive
        assert not (quick & ~exhaustive).any(), (scene, k)  # sound with a budget too
    assert lazy.stats.states > 0 and lazy.stats.timed_out == 0


@pytest.mark.parametrize("scene", ["avoidable_obstacle", "narrow_road", "goal_ahead"])
def test_qd_beyond_the_budget_is_decided_state_by_state(tmp_path: Path, scene: str) -> None:
    path = write_engine_file(tmp_path, scene, UNDER)
    result = compile_file(path)
    _, whole = run_queries(result, VerifyOptions(seed=1, out_dir=tmp_path / "whole", plots=False))
    _, small = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "small", plots=False,
                                                             max_states=3))
    exhaustive = {r.name: r for r in whole}
    lazy = {r.name: r for r in small}
    assert lazy["safe"].status == exhaustive["safe"].status, (lazy["safe"], exhaustive["safe"])
    assert exhaustive["safe"].method == "exhaustive"
    # the narrow road's pruned model is its start alone (off the road): within any budget
    assert lazy["safe"].method == ("on demand" if (exhaustive["safe"].states or 0) > 3 else "exhaustive")
    if exhaustive["safe"].status == "satisfied":
        # simulations and learning run under it; exhaustive queries under it are not decided (honestly)
        assert lazy["Prob"].status == "value" and lazy["Learn"].status == "value"
        assert lazy["Shielded"].status == "unknown" and "state by state" in (lazy["Shielded"].message or "")
    else:
        assert {lazy[n].status for n in ("Shielded", "Prob", "Learn")} == {"not_applicable"}


def test_the_fixed_continuations_are_tried_in_bounded_chunks(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The rows asked about together are proved in chunks of at most FIXED_PAIRS (row, action) pairs,
    with the proofs of one pass over all of them: a layer of a million states on 45 actions held 6.7 GB
    of the continuations' arrays at once."""
    path = write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"]})
    result = compile_file(path)
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    runs = simulate(data, runs=30, horizon_samples=horizon, seed=3)
    rows = np.column_stack([np.zeros(runs.states.shape[0]), runs.states[:, 0, :7]]).astype(np.int32)
    whole = on_demand(data, horizon)
    expected = whole._fixed_proofs(rows[:, 1:].astype(np.int64), 0)
    sizes: list[int] = []
    proofs: list[np.ndarray] = []
    fixed = ondemand.OnDemandShield._fixed_proofs

    def counted(self: ondemand.OnDemandShield, egos: np.ndarray, k: int) -> np.ndarray:
        sizes.append(egos.shape[0] * self.n_actions)
        proofs.append(fixed(self, egos, k))
        return proofs[-1]

    chunked = on_demand(data, horizon)
    monkeypatch.setattr(ondemand, "FIXED_PAIRS", 2 * chunked.n_actions)
    monkeypatch.setattr(ondemand.OnDemandShield, "_fixed_proofs", counted)
    chunked.masks_for(rows)
    assert len(sizes) == -(-rows.shape[0] // 2) and max(sizes) <= 2 * chunked.n_actions
    assert (np.concatenate(proofs) == expected).all() and expected.any()


def test_where_no_action_is_proved_in_time_learning_chooses_among_the_longest_safe(tmp_path: Path,
                                                                                   monkeypatch: pytest.MonkeyPatch
                                                                                   ) -> None:
    """A state whose search ran out of time before proving any action to the horizon has an empty row
    (sound); the runtime shield's answer there (the actions safe the longest) is kept, and learning's
    fallback chooses among those, not among all actions (a 30 s horizon past the traffic of a real
    scene: 233 of 352 learning episodes under `safe` collided choosing among all)."""
    import dataclasses

    from rac.learning.episodes import EpisodeBatch
    from rac.learning.strategy import allowed_actions

    path = write_engine_file(tmp_path, "avoidable_obstacle", {"safe": QUERIES["safe"]})
    result = compile_file(path)
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    shield = on_demand(data, horizon)
    lookahead = shield.lookahead
    assert lookahead is not None
    real = lookahead.decide

    def short_of_time(row):  # type: ignore[no-untyped-def]
        found = real(row)  # then as if the budget ran out one decision short of the horizon
        partial = np.zeros_like(found.mask)
        partial[np.flatnonzero(found.mask)[:1]] = True
        return dataclasses.replace(found, mask=partial, depth=max(1, found.target - 1), complete=False)

    monkeypatch.setattr(lookahead, "decide", short_of_time)
    monkeypatch.setattr(ondemand.OnDemandShield, "_fixed_proofs",
                        lambda self, egos, k: np.zeros((egos.shape[0], self.n_actions), dtype=bool))
    batch = EpisodeBatch(result, horizon_samples=horizon)
    batch.reset(1)
    row = batch.state_keys()
    assert not shield.masks_for(row).any()  # nothing proved to the horizon: the row stays empty
    longest = shield.fallback_for(row)
    assert longest.sum() == 1
    masks, empty = allowed_actions(batch, shield)
    assert empty.tolist() == [True] and (masks == longest).all()  # not every action of the model
    table = shields.synthesise(data, horizon)[1]
    assert not table.fallback_for(row).any()  # an exhaustive table knows nothing beyond its rows


def _searched_rows(tmp_path: Path, scene: str):  # type: ignore[no-untyped-def]
    """The scene's data, horizon and the state rows of 30 runs at each decision sample."""
    path = write_engine_file(tmp_path, scene, {"safe": QUERIES["safe"]})
    result = compile_file(path)
    data = result.model_data
    assert data is not None and result.automaton is not None
    horizon = result.automaton.steps
    runs = simulate(data, runs=30, horizon_samples=horizon, seed=3)
    rows = [np.column_stack([np.full(30, k), runs.states[:, k, :7]]).astype(np.int32)
            for k in range(0, horizon, data.decide_every)]
    return data, horizon, rows


def test_the_on_demand_shields_masks_do_not_depend_on_the_clock(tmp_path: Path,
                                                                monkeypatch: pytest.MonkeyPatch) -> None:
    """Its budget per state is search nodes, the same on every machine: on a machine so loaded that
    each reading of the clock is 15 ms after the last, the masks and the states whose budget ran out
    are those of an idle one (the old budget, 0.02 s a state, cut the searches there)."""
    from types import SimpleNamespace

    from rac.engine import lookahead

    data, horizon, rows = _searched_rows(tmp_path, "goal_behind_wall")
    # every row searched on its own (the fixed continuations tried first would prove most of them)
    monkeypatch.setattr(ondemand.OnDemandShield, "_fixed_proofs",
                        lambda self, egos, k: np.zeros((egos.shape[0], self.n_actions), dtype=bool))
    idle = on_demand(data, horizon)
    expected = [idle.masks_for(part) for part in rows]
    assert idle.stats.states > 0 and any(mask.any() for mask in expected)
    ticks = iter(range(10**9))
    monkeypatch.setattr(lookahead, "time", SimpleNamespace(perf_counter=lambda: next(ticks) * 0.015))
    loaded = on_demand(data, horizon)
    for part, mask in zip(rows, expected):
        assert (loaded.masks_for(part) == mask).all()
    assert loaded.stats == idle.stats and loaded.stats.clock == 0


def test_an_answer_the_shields_time_guard_cut_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The time guard is a safety net; where it cuts a search the mask depends on the machine, and the
    answers that used such masks say so (they said nothing)."""
    from rac.verify import symbolic

    path = write_engine_file(tmp_path, "goal_behind_wall", UNDER)
    monkeypatch.setattr(symbolic, "on_demand", lambda data, horizon, **kw: on_demand(data, horizon, seconds=1e-9, **kw))
    monkeypatch.setattr(ondemand.OnDemandShield, "_fixed_proofs",
                        lambda self, egos, k: np.zeros((egos.shape[0], self.n_actions), dtype=bool))
    context, results = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path, plots=False,
                                                                     max_states=3))
    found = {r.name: r for r in results}
    assert found["safe"].method == "on demand" and found["safe"].status == "satisfied"
    assert context.on_demand["safe"].stats.clock > 0
    for name in ("Prob", "Learn"):  # (Prob: the runs met the empty masks the guard left; that too depended on it)
        assert "time guard (1e-09 s a state) cut short" in (found[name].message or ""), found[name].message
    assert "time guard" not in (found["safe"].message or "")


def test_a_start_search_stopped_by_its_budget_counts_its_actions_as_at_least(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Qd beyond the budget is decided by a search from the start within a budget of work; where the
    budget stopped it after proving some actions, the others were not searched to the end, so the count
    of actions with a safe continuation is a lower bound (it read as exact), and says what stopped it."""
    from rac.verify import symbolic

    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"]})
    _, complete = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "a", plots=False,
                                                                max_states=3))
    monkeypatch.setattr(symbolic, "START_WORK", 45)  # 2 nodes of 9 actions over 2 samples: 1 action proved
    _, stopped = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "b", plots=False,
                                                               max_states=3))
    assert complete[0].status == stopped[0].status == "satisfied"
    assert "at the start 1 of 9 actions have" in (complete[0].message or ""), complete[0].message
    assert ("at the start at least 1 of 9 actions (the search stopped at its budget of 2 search nodes, the same "
            "on every machine)") in (stopped[0].message or ""), stopped[0].message


def _start_answers(tmp_path: Path, work: int | None = None) -> list[str]:
    """Qd's status and message on goal_behind_wall beyond a state budget of 3, its start search given ``work``
    (default: :data:`rac.verify.symbolic.START_WORK`)."""
    from rac.verify import symbolic

    tmp_path.mkdir(parents=True, exist_ok=True)
    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"]})
    options = VerifyOptions(seed=1, out_dir=tmp_path, plots=False, max_states=3)
    with pytest.MonkeyPatch.context() as patch:
        if work is not None:
            patch.setattr(symbolic, "START_WORK", work)
        [result] = run_queries(compile_file(path), options)[1]
    return [result.status, result.method or "", result.message or ""]


def test_the_start_searchs_verdict_does_not_depend_on_the_clock(tmp_path: Path,
                                                                 monkeypatch: pytest.MonkeyPatch) -> None:
    """The search from the start decides Qd within a budget of work, the same on every machine: on a
    machine so loaded that each reading of the clock is 15 s after the last, its verdicts (satisfied with
    every action it proves; UNKNOWN where the budget stops it) are an idle machine's. Its old limit, 20 s
    of wall clock, cut the search there (the count of actions read "at least", a harder scene UNKNOWN)."""
    from types import SimpleNamespace

    from rac.engine import lookahead

    idle = _start_answers(tmp_path / "idle"), _start_answers(tmp_path / "idle1", work=1)
    assert idle[0][:2] == ["satisfied", "on demand"] and "at the start 1 of 9 actions have" in idle[0][2]
    assert idle[1][0] == "unknown" and "its budget of 1 search node, the same on every machine" in idle[1][2]
    ticks = iter(range(10**9))
    monkeypatch.setattr(lookahead, "time", SimpleNamespace(perf_counter=lambda: next(ticks) * 15.0))
    loaded = _start_answers(tmp_path / "loaded"), _start_answers(tmp_path / "loaded1", work=1)
    assert loaded == idle


def test_a_start_search_its_safety_time_limit_stopped_says_it_depends_on_the_machine(
        tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """The start search's time limit is only a safety net; where it stops the search before its budget is
    spent, the verdict (here UNKNOWN) depends on the machine's speed and load, and says so: in the note the
    runner adds for every search its safety net cut (witness searches had it; the start search did not count)."""
    from rac.verify import symbolic

    monkeypatch.setattr(symbolic, "START_SAFETY_SECONDS", 1e-9)
    status, _, message = _start_answers(tmp_path)
    data = compile_file(tmp_path / "goal_behind_wall.ra").model_data
    assert status == "unknown" and data is not None
    assert ("it stopped at its safety time limit of 1e-09 s before spending its budget of "
            f"{symbolic.start_nodes(data):,} search nodes)") in message, message
    assert ("the search from the start ran into its safety time limit (1e-09 s) before spending its work budget, "
            "so this answer (its verdict, or its count of actions) depends on the machine's speed and load"
            ) in message, message
    assert message.count("speed and load") == 1, message


def test_max_seconds_bounds_the_start_search_and_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """``--max-seconds`` bounds Qd's search from the start (it had only its work budget and the 300 s safety
    net): on a clock that reads 15 s later at every look, a limit of 20 s stops it, and the answer names
    --max-seconds, not the safety net. Without the option the same clock leaves the verdict to the budget."""
    import time
    from types import SimpleNamespace

    from rac.engine import budget, lookahead

    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"]})
    frozen = time.perf_counter()
    monkeypatch.setattr(budget, "time", SimpleNamespace(perf_counter=lambda: frozen))  # the query's own clock
    ticks = iter(range(10**9))
    monkeypatch.setattr(lookahead, "time", SimpleNamespace(perf_counter=lambda: next(ticks) * 15.0))
    [limited] = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "a", plots=False,
                                                              max_states=3, max_seconds=20))[1]
    message = limited.message or ""
    assert "the time limit of 20 s (--max-seconds) before spending its budget of" in message, message
    assert limited.status != "satisfied" or "at least" in message, message
    assert "safety time limit" not in message, message
    [free] = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "b", plots=False,
                                                           max_states=3))[1]
    assert free.status == "satisfied" and "at the start 1 of 9 actions have" in (free.message or ""), free.message


def test_max_memory_bounds_the_start_search_and_says_so(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Qd's search from the start was checked against no memory limit (about 1 GB at its work budget's worst):
    under a --max-memory its next layer would pass, it stops before allocating it and the answer names the
    option, not the budget of search nodes."""
    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"]})
    monkeypatch.setattr(Lookahead, "_fixed", lambda self, states, k, held, remaining: np.zeros(states.shape[0],
                                                                                             dtype=np.int64))
    [result] = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path, plots=False, max_states=3,
                                                             max_bytes=2000))[1]
    message = result.message or ""
    assert result.status == "unknown", message
    assert "it stopped at the memory budget of 1.95 kB (--max-memory) before spending its budget of" in message, message


def test_the_start_search_counts_its_nodes(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Qd's search from the start runs up to half a minute at its budget's worst; it showed no bar, and off a
    terminal the progress lines counted nothing while it ran. It counts its search nodes."""
    from rac.output.progress import Heartbeat

    counts: list[tuple[int, str]] = []
    monkeypatch.setattr(Heartbeat, "count", lambda self, n, unit, what="": counts.append((n, unit)))
    monkeypatch.setattr(Lookahead, "_fixed", lambda self, states, k, held, remaining: np.zeros(states.shape[0],
                                                                                             dtype=np.int64))
    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"]})
    with Heartbeat("rac verify", enabled=False):
        [result] = run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path, plots=False,
                                                                 max_states=3))[1]
    assert result.method == "on demand", result.message
    nodes = [n for n, unit in counts if unit == "search nodes"]
    assert len(nodes) > 1 and nodes == sorted(nodes) and nodes[0] >= 1, counts


def test_max_seconds_is_checked_between_the_shields_searches(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """A query under the on-demand shield checked --max-seconds once per simulated sample, and one sample of
    thousands of runs may ask the shield for thousands of searches, each up to its 2 s guard: the query's limit
    is now checked between them. Here a limit that has passed by the first search the shield makes for `Prob`
    gives it up there (the old code asked the limit only after the sample, once the searches were done)."""
    from rac.engine.budget import TimeExceeded, TimeLimit
    from rac.verify import runner

    asking = [False]
    masks_for = ondemand.OnDemandShield.masks_for

    def watched(self: ondemand.OnDemandShield, states: np.ndarray) -> np.ndarray:
        asking[0] = True
        try:
            return masks_for(self, states)
        finally:
            asking[0] = False

    class PassedInSearches(TimeLimit):
        def check(self, *progress: int) -> None:
            if asking[0] and self.what == "query Prob":
                raise TimeExceeded(what=self.what, limit=1.0, seconds=1.5)

    monkeypatch.setattr(ondemand.OnDemandShield, "masks_for", watched)
    monkeypatch.setattr(runner, "TimeLimit", PassedInSearches)
    path = write_engine_file(tmp_path, "goal_behind_wall", {"safe": QUERIES["safe"], "Prob": UNDER["Prob"]})
    found = {r.name: r for r in run_queries(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path, plots=False,
                                                                                max_states=3, max_seconds=1.0))[1]}
    assert found["safe"].status == "satisfied" and found["safe"].method == "on demand"
    assert found["Prob"].status == "unknown", found["Prob"]
    assert found["Prob"].message == "query Prob: given up after 1.5 s, past the time limit of 1 s (--max-seconds)"


def test_a_state_asked_twice_at_once_is_counted_once(tmp_path: Path) -> None:
    """``stats.states`` counts distinct states (what a report cites as the shield's reach): runs that
    meet the same state at one sample asked about it together, and it was counted once per run."""
    data, horizon, rows = _searched_rows(tmp_path, "avoidable_obstacle")
    shield = on_demand(data, horizon)
    start = rows[0][:1]
    twice = shield.masks_for(np.concatenate([start, start, start]))
    assert twice.any() and (twice == twice[0]).all()
    assert shield.stats.states == 1


def test_an_on_demand_shield_is_not_saved_as_an_empty_table(tmp_path: Path) -> None:
    """Its rows are computed when asked, so a file of it held no state, and every mask read back from
    it was empty (or every action, with ``unseen="all"``): refused, naming what to save instead."""
    data, horizon, rows = _searched_rows(tmp_path, "avoidable_obstacle")
    shield = on_demand(data, horizon)
    assert shield.masks_for(rows[0]).any()
    with pytest.raises(ValueError, match="computes its masks state by state when asked and has no table to save"):
        shields.save(shield, tmp_path / "safe.shield.npz")
    assert not (tmp_path / "safe.shield.npz").exists()


def test_an_on_demand_shield_records_its_model(tmp_path: Path) -> None:
    """Its masks are searches against its own model's obstacles: like a table it records the model, so
    a StepShield of another scene refuses it (it took it, and called its masks exhaustive there)."""
    import dataclasses

    data, horizon, _ = _searched_rows(tmp_path, "avoidable_obstacle")
    shield = on_demand(data, horizon)
    assert shield.model == data.digest
    shields.StepShield(data, horizon, table=shield)  # its own model: used
    longer = dataclasses.replace(data, obs_length=tuple(n + 2 * data.scale for n in data.obs_length))
    with pytest.raises(ValueError, match="computed for another model"):
        shields.StepShield(longer, horizon, table=shield)
