"""The generated scenes of rac.model.scenes (highway, T-junction, overtaking, tutorial, the left turn): valid,
byte-stable CommonRoad files whose hazards are there by construction, answered by the engine and
emitted for UPPAAL like any user's scenario (benchmarks/queries.py runs every query on them)."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from engine_files import safety_source
from test_utap import compile_cli
from utap import Utap

import rac
from rac.compiler import compile_file
from rac.model import NativeModel
from rac.model.commonroad import load_scenario
from rac.model.scenes import SCENES, scene_bytes, write_scene
from rac.verify.context import VerifyOptions
from rac.verify.runner import run_queries

#: Per scene: lanelets, obstacles, and the settings of a small model over it.
EXPECTED = {"highway": (3, 3), "overtaking": (2, 2), "t_junction": (12, 2), "left_turn": (20, 3), "urban": (6, 0),
            "urban_head_on": (4, 1), "tutorial": (2, 3)}
SETTINGS = {
    "highway": "max_speed 30\naction turn in [-0.2, 0.2] step 0.2",
    "overtaking": "max_speed 25\naction turn in [-0.2, 0.2] step 0.2",
    "t_junction": "action turn in [0, 0.4] step 0.2",
    "tutorial": "action turn in [-0.2, 0.2] step 0.2",
    "left_turn": "action turn in [0, 0.4] step 0.2",
    "urban": "action turn in [0, 0.4] step 0.2",
    "urban_head_on": "action turn in [0, 0.4] step 0.2",
}
MODEL = """\
scenario "{name}.xml"
exponent 2
decide_period 2
granularity 0.25
action jerk in [-2, 2] step 2
{settings}
bind close = mindist() < 3 * collision_distance
"""
QUERIES = {"Qb": "E[] !collide() && !offroad()", "Qd": "strategy safe = control: A[] !collide() && !offroad()"}


def scene_file(folder: Path, name: str, horizon: int = 10) -> Path:
    write_scene(name, folder / f"{name}.xml")
    source = folder / f"{name}.ra"
    model = MODEL.format(name=name, settings=SETTINGS[name])
    source.write_text(safety_source("Scene", horizon, model, QUERIES), encoding="utf-8")
    return source


@pytest.mark.parametrize("name", sorted(SCENES))
def test_a_scene_is_a_stable_commonroad_file_rac_reads(name: str, tmp_path: Path) -> None:
    data = scene_bytes(name)
    assert data == scene_bytes(name)  # byte-stable
    path = write_scene(name, tmp_path / f"{name}.xml")
    scenario = load_scenario(path)
    assert (len(scenario.road), len(scenario.obstacles)) == EXPECTED[name]
    assert scenario.goal.regions and scenario.ego.velocity > 0


#: What the ego meets when it keeps its speed and heading, and at which sample (0.1 s each).
HAZARDS = {"highway": ("collide", 61), "overtaking": ("collide", 27), "t_junction": ("offroad", 33),
           "tutorial": ("collide", 36)}


@pytest.mark.parametrize("name", sorted(HAZARDS))
def test_keeping_speed_and_heading_fails_and_a_safe_run_exists(name: str, tmp_path: Path) -> None:
    """The hazard of each scene is real: the ego that keeps its speed and heading runs into the truck
    (highway, at 6.1 s), the tractor (overtaking, 2.7 s) or the slower car ahead (tutorial, 3.6 s), or
    straight on off the T-junction's road
    where the north arm is missing (3.3 s); and some run stays safe to the horizon (Qb), so a safety
    shield exists (Qd)."""
    result = compile_file(scene_file(tmp_path, name))
    assert result.ok, result.diagnostics
    model = NativeModel(result.model_data)
    state, first = model.initial_state(), {}
    for k in range(1, 101):
        state = model.sense(state)
        for label, holds in (("collide", model.collide(state, k)), ("offroad", model.offroad(state, k))):
            if holds:
                first.setdefault(label, k)
    label, sample = HAZARDS[name]
    assert min(first.items(), key=lambda item: item[1]) == (label, sample)
    answers = {a.name: a.status for a in run_queries(result, VerifyOptions(seed=1, out_dir=tmp_path / "o",
                                                                          plots=False))[1]}
    assert answers == {"Qb": "satisfied", "Qd": "satisfied"}


@pytest.mark.parametrize("name", ["highway", "overtaking", "t_junction"])
def test_the_scene_model_passes_uppaals_parser(name: str, tmp_path: Path, capsys: pytest.CaptureFixture[str],
                                                utap: Utap) -> None:
    utap.validate_files(*compile_cli(scene_file(tmp_path, name), tmp_path / f"{name}_model.xml", capsys))


def test_the_scenes_differ_in_kind() -> None:
    """Highway and overtaking are straight roads along x (a multi-lane one, and one lane each way);
    the T-junction has curved connectors."""
    highway = load_scenario_bytes("highway")
    overtaking = load_scenario_bytes("overtaking")
    junction = load_scenario_bytes("t_junction")
    assert {round(p.points[0][1], 2) for p in highway.road} == {0.0, 3.5, 7.0}
    assert max(len(p.points) for p in junction.road) > 20  # quarter circles
    headings = {round(o.waypoints[0].heading, 2) for o in overtaking.obstacles}
    assert headings == {0.0, round(np.pi, 2)}  # one vehicle each way


def test_the_urban_scenes_keep_their_promises(tmp_path: Path) -> None:
    """On the obstacle-free boulevard the ego that keeps its speed reaches the goal at 13.2 s, safely;
    on the head-on street it runs into car 91 at 10.3 s, while the car changes back to its side."""
    arrivals = {}
    for name, horizon in (("urban", 14), ("urban_head_on", 21)):
        result = compile_file(scene_file(tmp_path, name, horizon))
        assert result.ok, result.diagnostics
        data = result.model_data
        model = NativeModel(data)
        state = model.initial_state()
        for k in range(1, horizon * 10 + 1):
            state = model.sense(state)
            if model.collide(state, k) or model.offroad(state, k) or model.goal(state, k):
                arrivals[name] = (k, model.collide(state, k), model.offroad(state, k), model.goal(state, k))
                break
        if name == "urban_head_on":
            assert (data.goal_low, data.goal_high) == (194, 204)
            x, y, _ = model.obstacle_position(0, k)
            assert x == pytest.approx(200 - 10 * 10.3, abs=0.1) and 5.25 < y < 8.75  # changing lanes
    assert arrivals == {"urban": (132, False, False, True), "urban_head_on": (103, True, False, False)}


def load_scenario_bytes(name: str):
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        return load_scenario(write_scene(name, Path(folder) / f"{name}.xml"))


# ---------------------------------------------------------------- seeded scene sets
@pytest.mark.parametrize("kind", ["highway", "tutorial"])
def test_a_scene_set_is_seeded_and_keeps_the_ego_and_goal(kind: str, tmp_path: Path) -> None:
    from rac.model.scenes import scene_set, variant_bytes

    paths = scene_set(kind, 3, 5, tmp_path / "set")
    assert [p.name for p in paths] == [f"{kind}_5.xml", f"{kind}_6.xml", f"{kind}_7.xml"]
    assert paths[0].read_bytes() == variant_bytes(kind, 5)  # the same seed, the same bytes
    assert [p.read_bytes() for p in scene_set(kind, 3, 5, tmp_path / "again")] == [p.read_bytes() for p in paths]
    base = load_scenario(write_scene(kind, tmp_path / "base.xml"))
    starts = set()
    for path in paths:
        scenario = load_scenario(path)
        assert scenario.ego == base.ego and scenario.goal == base.goal and scenario.road == base.road
        assert [o.id for o in scenario.obstacles] == [o.id for o in base.obstacles]
        starts.add(tuple((o.waypoints[0].x, o.waypoints[0].velocity) for o in scenario.obstacles))
        model = NativeModel(compile_file(_set_model(tmp_path, path)).model_data)  # type: ignore[arg-type]
        assert not model.collide(model.sense(model.initial_state()), 1)  # a sensible start: no crash at once
    assert len(starts) == 3  # the obstacles differ from seed to seed
    with pytest.raises(ValueError, match="no variants"):
        variant_bytes("left_turn", 0)



def test_a_smaller_scene_set_removes_the_variants_of_the_larger_one(tmp_path: Path) -> None:
    """A set of 2 written over a set of 4 left variants 2 and 3, which a ScenarioEnv given the folder then
    trained on: the set's stale variants are removed, never a file rac did not write, nor another kind's set."""
    from rac.model.scenes import scene_set

    folder = tmp_path / "set"
    scene_set("highway", 4, 0, folder)
    tutorial = scene_set("tutorial", 1, 0, folder)  # another kind's set in the same folder stays
    (folder / "highway_9.xml").write_text("<commonRoad/> my own", encoding="utf-8")  # the user's: stays
    (folder / "highway_3.xml").rename(folder / "highway_10.xml")  # rac's variant 3 under another number: stays
    (folder / "highway_x.xml").write_text("", encoding="utf-8")
    written = scene_set("highway", 2, 0, folder)
    assert sorted(path.name for path in folder.iterdir()) == sorted(
        [*(path.name for path in written + tutorial), "highway_9.xml", "highway_10.xml", "highway_x.xml"])
    (folder / "highway_10.xml").unlink()
    kept = scene_set("highway", 1, 7, tmp_path / "kept")[0]
    (folder / "highway_7.xml").symlink_to(kept)  # the user's link to a variant kept elsewhere: stays
    scene_set("highway", 1, 1, folder)  # another seed: variant 0 is no longer the set's
    assert sorted(path.name for path in folder.glob("highway_*.xml")) == ["highway_1.xml", "highway_7.xml",
                                                                          "highway_9.xml", "highway_x.xml"]
    assert kept.is_file()


#: Rewrites a scene set in a child process whose files cannot grow past 1000 bytes (as a full disk):
#: every write fails partway through.
_FULL_DISK = """
import resource, signal, sys
import rac.model.scenes as scenes
made = {seed: scenes.variant_bytes("highway", seed) for seed in range(2)}  # made before the limit (a temporary file)
scenes.variant_bytes = lambda kind, seed: made[seed]
signal.signal(signal.SIGXFSZ, signal.SIG_IGN)  # a write past the limit fails with EFBIG, the process goes on
resource.setrlimit(resource.RLIMIT_FSIZE, (1000, 1000))
scenes.scene_set("highway", 2, 0, sys.argv[1])
"""


@pytest.mark.skipif(sys.platform == "win32", reason="RLIMIT_FSIZE is POSIX")
def test_an_interrupted_scene_set_leaves_the_complete_files(tmp_path: Path) -> None:
    """A write that fails partway (a full disk, a kill) left a truncated scene where the set was,
    which the next run read: each file is now written to a temporary file and moved into place."""
    from rac.model.scenes import scene_set

    folder = tmp_path / "set"
    complete = [path.read_bytes() for path in scene_set("highway", 2, 0, folder)]
    source = Path(rac.__file__).resolve().parents[1]
    run = subprocess.run([sys.executable, "-c", _FULL_DISK, str(folder)], capture_output=True, text=True,
                         env={**os.environ, "PYTHONPATH": str(source)}, timeout=300)
    assert run.returncode != 0 and "File too large" in run.stderr, run.stderr
    assert [(folder / f"highway_{i}.xml").read_bytes() for i in range(2)] == complete
    assert sorted(path.name for path in folder.iterdir()) == ["highway_0.xml", "highway_1.xml"]  # no temporaries

def test_the_command_says_what_it_cannot_write(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """``python -m rac.model.scenes`` ended in a traceback on a missing folder, a file where the set's
    folder goes or ``--count 0``; the atomic write named its temporary file, not the one asked for."""
    from rac.model.scenes import main

    (tmp_path / "a_file").write_text("", encoding="utf-8")
    missing = tmp_path / "missing" / "x.xml"
    for argv, said in ((["highway", str(missing)], f"No such file or directory: '{missing}'"),
                       (["highway", str(tmp_path / "a_file"), "--count", "2"], "File exists"),
                       (["highway", str(tmp_path / "set"), "--count", "0"], "at least one scene, not 0"),
                       # numpy's "expected non-negative integer" named no seed
                       (["highway", str(tmp_path / "set"), "--count", "1", "--seed", "-5"], "from 0 on, not -5"),
                       # os.replace named the temporary file too
                       (["highway", str(tmp_path)], f"Is a directory: '{tmp_path}'")):
        with pytest.raises(SystemExit) as exit_:
            main(argv)
        assert exit_.value.code == 2
        error = capsys.readouterr().err
        assert said in error and "Traceback" not in error and ".tmp" not in error, error

def _set_model(folder: Path, scenario: Path) -> Path:
    source = folder / f"{scenario.stem}.ra"
    model = MODEL.format(name=scenario.stem, settings=SETTINGS["highway"]).replace(
        f'"{scenario.stem}.xml"', f'"{scenario}"')
    source.write_text(safety_source("Scene", 10, model, QUERIES), encoding="utf-8")
    return source
