"""MuJoBan's physical behaviour against the original's measured values
(`envs.mujoban.behaviour`; the original's values are committed in
results/physics_behaviour.json by benchmarks/physics_behaviour.py)."""

from __future__ import annotations

import json
import sys
from pathlib import Path

import numpy as np
import pytest

from envs.mujoban import behaviour

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "results" / "physics_behaviour.json"


@pytest.fixture(scope="module")
def level_file(tmp_path_factory):
    path = tmp_path_factory.mktemp("behaviour") / "level.txt"
    path.write_text(behaviour.level_text())
    return path


def _script():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import physics_behaviour
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    return physics_behaviour


def _measure(level_file, **overrides):
    return _script().measure_ours(overrides, level_file)


def test_the_default_model_behaves_as_the_original_within_tolerance(level_file):
    original = json.loads(RESULTS.read_text())["original"]
    assert set(original) == set(behaviour.QUANTITIES)
    ours = _measure(level_file)
    off = {
        q: (ours[q], original[q])
        for q in behaviour.QUANTITIES
        if not behaviour.within_tolerance(ours[q], original[q])
    }
    assert not off, f"quantities off the original's (ours, original): {off}"


def test_the_scenarios_tell_friction_and_the_walker_apart(level_file):
    """The checks can fail: 10 N does not move the box (floor friction holds
    12.3 N), 20 N does and 40 N more; a model with 10x the floor friction
    holds a 20 N push, which the tolerance tells from the default."""
    ours = _measure(level_file)
    assert ours["slide_10N_m"] < 0.002 < 0.3 < ours["slide_20N_m"] < ours["slide_40N_m"]
    assert ours["roll_m"] > 0.5 and ours["coast_m"] > 0.1 and ours["push_box_m"] > 1.0
    env = _script().ours_env({}, level_file)
    try:
        model = env.physics.model.ptr
        # The box-floor contacts are explicit contact pairs (their own friction).
        assert model.npair >= 1
        model.pair_friction[:, :2] *= 10
        stuck = behaviour.measure(env.physics)
    finally:
        env.close()
    assert stuck["slide_20N_m"] < 0.002
    assert not behaviour.within_tolerance(stuck["slide_20N_m"], ours["slide_20N_m"])


def test_tolerance_is_relative_with_an_absolute_floor():
    assert behaviour.within_tolerance(1.0095, 1.0)
    assert not behaviour.within_tolerance(1.02, 1.0)
    assert behaviour.within_tolerance(0.0015, 0.0)
    assert not behaviour.within_tolerance(0.003, 0.0)


def test_a_model_without_the_parts_is_refused_naming_them():
    import mujoco

    model = mujoco.MjModel.from_xml_string("<mujoco><worldbody/></mujoco>")
    with pytest.raises(ValueError, match="root_x"):
        behaviour._Parts(model)


def test_the_board_physics_benchmark_times_every_setting_against_the_default():
    sys.path.insert(0, str(ROOT / "benchmarks"))
    try:
        import board_physics
    finally:
        sys.path.remove(str(ROOT / "benchmarks"))
    rows = board_physics.measure("mujoxo/optimal", steps=30, rounds=2)
    assert [r["setting"] for r in rows] == list(board_physics.SETTINGS)
    assert rows[0]["x_default_rounds"] == [1.0, 1.0]
    assert all(r["mj_steps_per_s"] > 0 and len(r["x_default_rounds"]) == 2 for r in rows)


def test_the_walker_rolls_from_rest_to_a_top_speed_and_an_obstacle_is_refused(tmp_path):
    """`behaviour.roll_distances` on the corridor: non-decreasing distances,
    a top speed reached (the last steps equal); `steer_angles` turns past a
    quarter turn in 20 steps; in the small room of `LEVEL` the walker meets
    a wall, which is refused, not measured."""
    import envs

    corridor = tmp_path / "corridor.txt"
    corridor.write_text(behaviour.level_text(behaviour.CORRIDOR))
    env = envs.load(
        "mujoban/level1",
        levels=str(corridor),
        grid_shape=behaviour.CORRIDOR_SHAPE,
        **envs.no_cameras("mujoban/level1"),
    )
    env.reset()
    distances = behaviour.roll_distances(env.physics, 140, 50)
    steps = np.diff(distances)
    assert (steps >= 0).all() and steps[-1] == pytest.approx(steps[-2], rel=1e-3)
    assert 1.0 < steps[-1] / 0.05 < 20.0  # m/s
    assert distances[-1] < 36.0  # it stayed in the corridor's open cells
    env.reset()
    turned = behaviour.steer_angles(env.physics, 20, 50)
    assert (np.diff(turned) > 0).all() and np.pi / 2 < turned[-1] < 20 * np.pi
    env.close()
    room = tmp_path / "room.txt"
    room.write_text(behaviour.level_text())
    env = envs.load("mujoban/level1", levels=str(room), **envs.no_cameras("mujoban/level1"))
    env.reset()
    with pytest.raises(ValueError, match="met something"):
        behaviour.roll_distances(env.physics, 60, 50)
    env.close()


@pytest.mark.slow
def test_no_solved_level_beats_the_physical_limit_and_the_files_must_match(tmp_path):
    """`benchmarks/physical_limit.py` on the committed hard-level files: its
    lower bound holds for every level the agent solved, the levels pair by
    position, and files of two level files are refused in one line."""
    import subprocess

    out = tmp_path / "limit.json"
    command = [sys.executable, str(ROOT / "benchmarks" / "physical_limit.py")]
    subprocess.run(
        command + ["--json", str(out)], check=True, capture_output=True, cwd=ROOT, timeout=600
    )
    result = json.loads(out.read_text())
    levels = result["levels"]
    assert [x["position"] for x in levels] == list(range(200))
    assert all(x["steps"] >= x["bound_steps"] for x in levels if x["solved"])
    assert result["summary"]["solved"]["levels"] == sum(x["solved"] for x in levels)
    assert result["limit"]["steps_first_cell"] > 1  # from rest, not at top speed
    other = ROOT / "results" / "agent" / "boxoban_medium-valid-000_first100-pegs.json"
    done = subprocess.run(
        command + ["--rows", str(other)], capture_output=True, text=True, cwd=ROOT, timeout=600
    )
    assert done.returncode == 2 and "same level file" in done.stderr
