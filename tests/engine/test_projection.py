"""The size projection of a stopped exploration (rac.engine.budget.projected_states) against the real
layer counts (issue 20: the projection that spread a decision's growth over every sample was 2.8x too
high on one file and ~3x too low on another — states branch only at decisions).

Each example's model and benchmarks/zam_ramp.ra's (over a ramp built in code, tests/support/tiny_scenarios.py)
is explored in full over a short horizon; the projection from the layers a budget of half, and of a
quarter, of the states would have let through must be within :data:`FACTOR` of the real count."""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np
import pytest
from tiny_scenarios import ramp

from rac.compiler import compile_file
from rac.engine.budget import BudgetExceeded, projected_states
from rac.engine.explore import explore
from rac.model.data import ModelData

REPO = Path(__file__).resolve().parents[2]
#: The projection is within this factor of the real count (either way).
FACTOR = 1.5
#: Per model: the horizon explored in full (samples; about a million states at most).
HORIZONS = {"examples/left_turn/model.ra": 6, "examples/paper/model.ra": 100, "benchmarks/zam_ramp.ra": 30}


def model_data(name: str, folder: Path) -> ModelData:
    path = REPO / name
    if name == "benchmarks/zam_ramp.ra":  # its scenario is CommonUppRoad's: a ramp of our own instead
        (folder / "ramp.xml").write_bytes(ramp(5.0))
        text = re.sub(r'scenario\s+"[^"]*"', 'scenario "ramp.xml"', path.read_text(encoding="utf-8"))
        text = "\n".join(line for line in text.splitlines() if not re.match(r"\s*start_(x|y|heading|speed)\b", line))
        path = folder / "zam_ramp.ra"
        path.write_text(text, encoding="utf-8")
    result = compile_file(path)
    assert result.model_data is not None, result.diagnostics
    return result.model_data


def test_every_example_is_covered() -> None:
    assert {str(p.relative_to(REPO)) for p in REPO.glob("examples/**/model.ra")} <= set(HORIZONS)


@pytest.mark.parametrize("prune", [False, True], ids=["whole", "pruned"])
@pytest.mark.parametrize("name", sorted(HORIZONS))
def test_the_projection_is_near_the_real_count(name: str, prune: bool, tmp_path: Path) -> None:
    data = model_data(name, tmp_path)
    horizon = HORIZONS[name]
    graph = explore(data, horizon_samples=horizon, prune_unsafe=prune)
    layers = np.bincount(graph.states[:, 0], minlength=horizon + 1).tolist()
    real = sum(layers)
    for share in (2, 4):
        # the layers complete before a budget of real / share states stops the exploration
        k = int(np.searchsorted(np.cumsum(layers), real // share, side="right")) - 1
        projected = projected_states(layers[:k + 1], data.decide_every, horizon)
        assert projected is not None, (name, share, k)
        assert real / FACTOR <= projected[0] <= real * FACTOR, (name, prune, share, k, projected[0], real)


def test_the_budget_message_projects_by_decision(tmp_path: Path) -> None:
    """examples/left_turn/model.ra: 81 successors per decision, a decision every 2 samples, layers
    constant in between — stopped while building sample 5, the projection to sample 6 is the real count."""
    data = model_data("examples/left_turn/model.ra", tmp_path)
    real = explore(data, horizon_samples=6).n_states
    with pytest.raises(BudgetExceeded) as raised:
        explore(data, horizon_samples=6, max_states=100_000)
    assert raised.value.sample == 5 and raised.value.projected_states == real
    assert "growing ×81 per decision" in str(raised.value)
