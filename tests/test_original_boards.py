"""The adapter that lets our agent play the original MuJoXO and MuJoGo
(``benchmarks/original_boards.py``): the description read from the
original's model matches its geometry, no privileged observation reaches
the agent, the arm's joints decode exactly, and a MuJoXO game plays to its
end. Skipped unless DeepMind's ``physics_planning_games`` is importable
(``PYTHONPATH=/tmp/peer``, see ``../shared/peer/README.md``)."""

from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("physics_planning_games.board_games")

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "benchmarks"))

import original_boards as ob  # noqa: E402

PRIVILEGED = ("board_state", "move_history", "markers/position", "jaco_arm/joints_torque")


@pytest.fixture(scope="module")
def xo():
    """The original MuJoXO without shadows (cheaper frames), its description."""
    env = ob.original_env("xo", seed=3, time_limit=30.0, shadows=False)
    raw = env.reset()
    yield env, raw, ob.original_description(env, 30.0)
    ob.close_env(env)


def _true_joints(env) -> np.ndarray:
    bind = env.physics.bind
    return np.r_[bind(env.task.arm.joints).qpos, bind(env.task.hand.joints).qpos]


def test_projected_points_land_on_their_own_squares(xo):
    env, _, description = xo
    camera = description.front_camera_2
    assert camera.shape == ob.FRAME and camera.multisamples == 4
    assert description.game == "tic_tac_toe" and description.num_points == 9
    # Which geom each pixel shows, in the original's own rendering of its camera.
    seg = env.physics.render(*ob.FRAME, camera_id=ob.ORIGINAL_CAMERA, segmentation=True)[..., 0]
    squares = [env.physics.bind(g).element_id for g in env.task._board._geoms.ravel()]
    robot = {env.physics.bind(g).element_id for g in env.task.arm.mjcf_model.find_all("geom")}
    pixels = camera.project(np.asarray(description.point_positions))
    hits = 0
    for point, (row, col) in enumerate(pixels):
        geom = int(seg[int(row), int(col)])
        if geom in robot:  # hidden by the arm
            continue
        assert geom == squares[point], f"point {point} lands on geom {geom}"
        hits += 1
    assert hits >= 5
    # A pad lies inside its square; the board's half covers the outer squares.
    assert 0 < description.pad_half < 0.05 and description.board_half == pytest.approx(0.15)


def test_the_arm_model_at_the_decoded_joints_is_the_originals(xo):
    import mujoco

    env, raw, description = xo
    adapter = ob.Adapter(env, description)
    model = description.arm.model()
    data = mujoco.MjData(model)
    ids = [model.joint(name).id for name in description.arm.joint_names]
    rng = np.random.default_rng(0)
    timestep = adapter.adapt(raw, 0)
    for step in range(1, 6):
        q = timestep.observation["arm/joints_pos"]
        np.testing.assert_allclose(q, _true_joints(env), atol=1e-9)
        data.qpos[model.jnt_qposadr[ids]] = q
        mujoco.mj_kinematics(model, data)
        np.testing.assert_allclose(
            data.site(description.arm.pinch_site).xpos,
            timestep.observation["arm/pinch_site_pos"],
            atol=1e-9,
        )
        spec = env.action_spec()
        timestep = adapter.adapt(env.step(rng.uniform(spec.minimum, spec.maximum)), step)


def test_no_privileged_observation_reaches_the_agent(xo):
    env, raw, description = xo
    assert all(key in raw.observation for key in PRIVILEGED[:1] + PRIVILEGED[2:])
    timestep = ob.Adapter(env, description).adapt(raw, 0)
    obs = timestep.observation
    assert set(obs) == set(ob.AGENT_KEYS)
    for key in PRIVILEGED + ("front_camera",):
        with pytest.raises(KeyError):
            obs[key]
    assert obs[ob.CAMERA].shape == ob.FRAME + (3,) and obs["agent_player"][0] == 0


def test_go_description_from_the_originals_board():
    env = ob.original_env("go", seed=0, time_limit=45.0, shadows=False)
    try:
        env.reset()
        d = ob.original_description(env, 45.0)
    finally:
        ob.close_env(env)
    points = np.asarray(d.point_positions)
    assert d.game == "go" and d.num_points == 49 and d.pass_action == 49
    # The referee's komi (OpenSpiel's default), not the 5.5 GNU Go is told.
    assert d.komi == 7.5 and not d.allow_double_pass and d.registering == "fingers"
    gaps = np.diff(points.reshape(7, 7, 3)[:, :, 0], axis=1)
    np.testing.assert_allclose(gaps, 0.1, atol=1e-12)
    assert np.all(np.abs(points[:, :2] - d.board_centre).max(axis=0) < d.board_half)
    for side, zone in d.pass_zones.items():
        x = zone["centre"][0]
        assert abs(x - d.board_centre[0]) - zone["half"][0] >= d.board_half - 1e-9, side


def test_a_mujoxo_game_plays_to_its_end():
    run = ob.play("xo", 1, seed=0, time_limit=30.0, progress=False, shadows=False)
    (row,) = run["rows"]
    assert row["outcome"] in ("win", "draw", "loss"), row
    assert row["estimates"] == row["steps"] > 0
    assert row["estimates_right"] >= 0.9 * row["estimates"]
    assert run["summary"]["games"] == 1
