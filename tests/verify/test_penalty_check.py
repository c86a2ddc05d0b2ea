"""rac.verify.penalties: W1011 for a penalty no action avoids, the line saying there is none, and the
check said not done beyond its budget (tests/support/spawn_scene.py: the highway of
:mod:`rac.model.scenes`, its truck inside the unsafe distance at the start, or away).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from spawn_scene import AWAY, SPAWNED, spawn_program, write_spawn

from rac.check.analysis.priority import p2_target
from rac.cli.main import main
from rac.core.diagnostics import Severity
from rac.verify.context import Context, VerifyOptions
from rac.verify.penalties import PENALTY_STATES, check_penalties, penalised_locations, render_penalties


def test_traffic_spawned_inside_the_unsafe_distance_is_w1011_at_the_start(tmp_path: Path) -> None:
    check = check_penalties(Context(spawn_program(tmp_path, SPAWNED), VerifyOptions()))
    assert check.done and check.samples == check.horizon_samples == 4
    assert list(check.counts) == ["sa"]  # `pr` is penalised nowhere
    [warning] = check.diagnostics
    assert warning.code == "W1011" and warning.severity is Severity.WARNING
    assert warning.span is not None and warning.span.line == 19  # the scenario line
    first = warning.data["first"]
    assert isinstance(first, dict)
    assert (first["sample"], first["time"], first["x"], first["y"], first["v"], first["head"]) == (0, 0, 30, 5.25,
                                                                                                   20, 0)
    assert first["locations"] == ["Unsafe"]
    assert len(first["actions"]) == 9  # every (jerk, turn) pair: none avoids it
    assert warning.data["states"] == check.counts["sa"]
    assert warning.message == (f"every allowed action is penalised (`sa`) in {check.counts['sa']} decision states "
                               "from t = 0 s")
    assert "t = 0 s (sample 0), the ego at x = 30 m, y = 5.25 m, v = 20 m/s" in warning.notes[0].message
    assert "spawning inside the unsafe distance" in warning.hints[0]
    assert check.message.endswith("up to the horizon (4 samples) (W1011)")


def test_the_truck_away_gives_no_warning_and_says_so(tmp_path: Path) -> None:
    check = check_penalties(Context(spawn_program(tmp_path, AWAY), VerifyOptions()))
    assert check.done and check.diagnostics == () and check.counts == {}
    assert check.message == (f"none: at each of the {check.decisions} decision states up to the horizon (4 samples) "
                             "some allowed action avoids every penalty of `sa`")
    assert render_penalties(check).splitlines() == [
        "Checking penalties that no action avoids", f" -- {check.message}",
        f"    {check.states:,} states, horizon 4 samples"]


def test_beyond_the_budget_the_check_says_how_far_it_went(tmp_path: Path) -> None:
    context = Context(spawn_program(tmp_path, SPAWNED), VerifyOptions())
    whole = check_penalties(context)
    cut = check_penalties(context, max_states=whole.states - 1)
    assert cut.done and cut.samples < cut.horizon_samples == 4
    reach = f"in the first {cut.samples} samples of 4 (by sample {cut.samples + 1} the product has more than"
    assert reach in cut.message
    assert cut.diagnostics[0].data["first"]["sample"] == 0  # type: ignore[index]
    assert 0 < cut.counts["sa"] < whole.counts["sa"]  # only the decisions whose samples were explored
    none = check_penalties(context, max_states=3)
    assert not none.done and none.diagnostics == ()
    assert none.message == "not checked: by sample 1 the product has more than 3 states, --max-states"


def test_the_check_fits_beside_the_kept_graphs(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """Regression: the check's product was held to --max-memory alone, not to what the graphs kept for
    later queries leave of it (:meth:`Context.memory_left`), and its reason did not say what holds the rest."""
    program = spawn_program(tmp_path, SPAWNED)
    assert check_penalties(Context(program, VerifyOptions())).done
    monkeypatch.setattr(Context, "memory_left", lambda self: 1)
    monkeypatch.setattr(Context, "kept_note", lambda self: " (KEPT GRAPHS)")
    refused = check_penalties(Context(program, VerifyOptions()))
    assert not refused.done and refused.message.startswith("not checked: ")
    assert refused.message.endswith("(KEPT GRAPHS)")


def test_the_budget_is_the_checks_own_or_max_states_when_smaller(tmp_path: Path) -> None:
    program = spawn_program(tmp_path, SPAWNED)
    assert not check_penalties(Context(program, VerifyOptions(max_states=3))).done
    assert check_penalties(Context(program, VerifyOptions(max_states=10 * PENALTY_STATES))).done


def test_penalties_are_p2s(tmp_path: Path) -> None:
    program = spawn_program(tmp_path, AWAY)
    automaton = program.automaton
    assert penalised_locations(automaton) == {"sa": p2_target(automaton, 0).watched,
                                              "pr": p2_target(automaton, 1).watched} == {
        "sa": (False, True), "pr": (False, False)}
    # without a priority: the rewards the objective weighs positively
    alone = spawn_program(tmp_path / "alone", AWAY, priority=None, objective="sa - pr").automaton
    assert penalised_locations(alone) == {"sa": (False, True)}


def test_no_penalty_anywhere_needs_no_exploration(tmp_path: Path) -> None:
    program = spawn_program(tmp_path, SPAWNED, priority=None, objective="pr")
    check = check_penalties(Context(program, VerifyOptions()))
    assert check.done and check.states == 0 and check.diagnostics == ()
    assert check.message.startswith("no location penalises an objective")


@pytest.mark.parametrize("truck", [SPAWNED, AWAY])
def test_rac_verify_prints_the_check_and_its_json(tmp_path: Path, truck: tuple[float, float],
                                                  capsys: pytest.CaptureFixture[str]) -> None:
    path = write_spawn(tmp_path, truck)
    assert main(["verify", str(path)]) == 0  # a warning: the exit code is the queries'
    out = capsys.readouterr().out
    assert ("warning[W1011]" in out) == (truck == SPAWNED)
    assert "Checking penalties that no action avoids\n -- " in out
    assert main(["verify", str(path), "--format", "json"]) == 0
    report = json.loads(capsys.readouterr().out)
    penalties = report["penalties"]
    assert penalties["done"] and penalties["samples"] == 4
    assert [d["code"] for d in penalties["diagnostics"]] == (["W1011"] if truck == SPAWNED else [])
    assert (penalties["unavoidable"] != {}) == (truck == SPAWNED)


def test_a_check_cut_short_by_max_states_leaves_the_exit_code_to_the_queries(tmp_path: Path,
                                                                          capsys: pytest.CaptureFixture[str]) -> None:
    # decided (docs/verify.md): the check is advice, not a query; finding W1011 exits 0, so not finishing
    # the search cannot exit 4, which says a query was left undecided (rac check: W1008 only when required)
    path = write_spawn(tmp_path, SPAWNED)
    assert main(["verify", str(path), "--max-states", "3", "--format", "json"]) == 0
    penalties = json.loads(capsys.readouterr().out)["penalties"]
    assert penalties["done"] is False and penalties["message"].startswith("not checked: ")
    assert main(["verify", str(path), "--max-states", "3"]) == 0
    assert " -- not checked: by sample 1 the product has more than 3 states, --max-states" in capsys.readouterr().out
