"""The fuzzer (tests/fuzz.py) in the suite: a bounded run over mutants of the shipped `.ra` files must
find no internal error, no hang and no misbehaving `rac fmt`; long runs are `python tests/fuzz.py
--minutes N` (docs/benchmarks.md)."""

from __future__ import annotations

from pathlib import Path

import pytest
from fuzz import fuzz

from rac.cli.main import main

ROOT = Path(__file__).resolve().parents[1]


@pytest.mark.parametrize("seed", [1, 2])
def test_mutants_of_the_shipped_files_never_fail_internally(seed: int) -> None:
    report = fuzz(seed, inputs=300)
    assert report.counts["inputs"] == 300
    assert not report.failures, report.failures[0][:1] + (report.failures[0][2],)
    assert report.counts["check exit 0"] > 0  # some mutants still check, and went through fmt and both targets


def test_a_penalty_whose_sum_no_float_holds_is_reported(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """The fuzzer's first find: `sa = sa - 1e308` checks each number, but P2's worst objective over
    the horizon is about 3e310, and printing it crashed the check (OverflowError)."""
    text = (ROOT / "stdlib" / "driving.ra").read_text(encoding="utf-8").replace("sa = sa - 100", "sa = sa - 1e308")
    source = tmp_path / "huge.ra"
    source.write_text(text, encoding="utf-8")
    assert main(["check", str(source)]) == 1
    out = capsys.readouterr()
    assert "internal error" not in out.err and "error[E0" in out.out
