"""Queries under a strategy that provably does not exist are ``not_applicable``, not UNKNOWN.

On the tiny narrow road (1 m wide, narrower than the ego) no strategy keeps the ego on the road, so
Qd (``control: A[] !collide() && !offroad()``) is not satisfied: every query under it, and under a
strategy learned under it, has nothing to be decided on. The failed Qd sets the exit code (1).
"""

from __future__ import annotations

import json
from pathlib import Path

import pytest
from engine_files import write_engine_file

from rac.cli.main import main
from rac.compiler import compile_file
from rac.verify.context import VerifyOptions
from rac.verify.runner import verify

QUERIES = {
    "safe": "strategy safe = control: A[] !collide() && !offroad()",
    "Shielded": "A[] !collide() under safe",
    "ProbShielded": "Pr[<=2](<> collide()) under safe",
    "fast": "strategy fast = maxE(sa)[<=4]{Tiny.location}->{x}: <> time >= 4 under safe",
    "UnderFast": "A[] !collide() under fast",
    "Stays": "E[] !collide() && !offroad()",
}


def test_queries_under_a_missing_strategy_are_not_applicable(tmp_path: Path) -> None:
    path = write_engine_file(tmp_path, "narrow_road", QUERIES)
    results = {r.name: r for r in verify(compile_file(path), VerifyOptions(seed=1, out_dir=tmp_path / "out"))}
    assert results["safe"].status == "not satisfied"
    assert "no strategy keeps `!collide() && !offroad()` from the start" in (results["safe"].message or "")
    for name in ("Shielded", "ProbShielded", "fast", "UnderFast"):
        assert results[name].status == "not_applicable", (name, results[name])
    assert "does not exist" in (results["Shielded"].message or "")
    # a strategy learned under the missing one is missing too, and says which query defined it
    assert "defining query fast is not applicable" in (results["UnderFast"].message or "")
    assert "defining query safe" in (results["fast"].message or "") or "`safe`" in (results["fast"].message or "")
    assert results["Stays"].status == "not satisfied"


def test_not_applicable_in_json_and_the_exit_code(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    queries = {k: QUERIES[k] for k in ("safe", "Shielded")}
    path = write_engine_file(tmp_path, "narrow_road", queries)
    # the failed defining query sets the exit code (1), not the inapplicable one
    assert main(["verify", str(path), "--format", "json", "--seed", "1", "--out", str(tmp_path / "o")]) == 1
    document = json.loads(capsys.readouterr().out)
    rows = document["results"]
    statuses = {row["name"]: row["status"] for row in rows}
    assert statuses == {"safe": "not satisfied", "Shielded": "not_applicable"}


def test_alone_a_not_applicable_query_does_not_fail(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = write_engine_file(tmp_path, "narrow_road", {k: QUERIES[k] for k in ("safe", "Shielded")})
    # selected alone, the strategy is computed for it first; the query is still not applicable
    code = main(["verify", str(path), "--query", "Shielded", "--seed", "1", "--out", str(tmp_path / "o")])
    out = capsys.readouterr().out
    assert "Not applicable" in out
    assert code == 1  # the defining query ran for it, and failed


def test_queries_under_a_reachability_strategy_say_it_is_not_kept(tmp_path: Path) -> None:
    """`strategy reach = control: E<> goal() && !offroad()` is decided, not kept: a query `under reach` said
    the strategy "has not been computed (it is defined by a query that was skipped or failed; run it
    first)", though its query had just run and held. It is not answered and says why; one that fails (the
    narrow road: never on it) is not applicable."""
    queries = {"reach": "strategy reach = control: E<> goal() && !offroad()", "Under": "E<> goal() under reach",
               "ProbUnder": "Pr[<=2](<> goal()) under reach"}
    results = {r.name: r for r in verify(compile_file(write_engine_file(tmp_path, "goal_ahead", queries)),
                                         VerifyOptions(seed=1, out_dir=tmp_path / "out"))}
    assert results["reach"].status == "satisfied"
    for name in ("Under", "ProbUnder"):
        assert results[name].status == "unsupported", results[name]
        assert "`reach` is a reachability strategy" in (results[name].message or "")
        assert "skipped or failed" not in (results[name].message or "")
    failed = {r.name: r for r in verify(compile_file(write_engine_file(tmp_path, "narrow_road", queries)),
                                        VerifyOptions(seed=1, out_dir=tmp_path / "out2"))}
    assert failed["reach"].status == "not satisfied" and failed["Under"].status == "not_applicable"



def test_rac_check_warns_of_a_query_under_a_reachability_strategy(tmp_path: Path) -> None:
    """`rac check` accepted `E<> goal() under reach` silently, though rac verify never answers it: it now
    warns (W0605) at each query under `reach`, and not at one under a safety strategy (kept)."""
    queries = {"reach": "strategy reach = control: E<> goal() && !offroad()", "Under": "E<> goal() under reach",
               "ProbUnder": "Pr[<=2](<> goal()) under reach", "safe": QUERIES["safe"], "Shielded": QUERIES["Shielded"],
               "fast": "strategy fast = maxE(sa)[<=4]{Tiny.location}->{x}: <> time >= 4 under reach"}
    path = write_engine_file(tmp_path, "goal_ahead", queries)
    lines = path.read_text(encoding="utf-8").splitlines()
    flagged = [d for d in compile_file(path).diagnostics if d.code == "W0605"]
    assert [lines[d.span.line - 1].split()[1] for d in flagged if d.span is not None] == ["Under:", "ProbUnder:",
                                                                                         "fast:"]
    assert all("`under reach` names a reachability strategy" in d.message for d in flagged)


def test_a_strategy_defined_again_replaces_the_earlier_one(tmp_path: Path) -> None:
    """`S` defined as a reachability strategy, then again as a shield: a query `under S` was refused as
    "a reachability strategy" (the first definition's record stayed); it is answered under the shield,
    and rac check warns of nothing (W0605 follows the latest definition too)."""
    queries = {"r": "strategy S = control: E<> goal() && !offroad()",
               "s": "strategy S = control: A[] !collide() && !offroad()", "U": "A[] !collide() under S"}
    compiled = compile_file(write_engine_file(tmp_path, "goal_ahead", queries))
    assert not [d for d in compiled.diagnostics if d.code == "W0605"]
    results = {r.name: r for r in verify(compiled, VerifyOptions(seed=1, out_dir=tmp_path / "out"))}
    assert results["s"].status == "satisfied"
    assert results["U"].status == "satisfied", results["U"]

