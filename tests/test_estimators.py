"""Estimators turn observations into the planners' abstract states."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from abstract_planners.sokoban import SokobanState
from driving import push_box
from envs.core import Environment
from envs.mujoban import sources
from envs.mujoban.levels import BOXOBAN_DIR, Level, read_levels
from envs.mujoban.task import Mujoban
from hier_agents.estimators import (
    BoardEstimator,
    EntityLayerEstimator,
    EstimationError,
    OracleEstimator,
    rounded_state,
)

NO_CAMERAS = {"top_camera": None, "egocentric_camera": None}


def test_mujoban_estimators_read_the_level_at_reset():
    path = BOXOBAN_DIR / "medium-valid-000.txt"
    env = envs.load("mujoban/level5", seed=0, levels=str(path), **NO_CAMERAS)
    for level in read_levels(path)[:3]:
        timestep = env.reset()
        expected = SokobanState.from_level(level)
        for estimator in (EntityLayerEstimator(env), OracleEstimator(env)):
            assert estimator.privileged
            estimator.reset(env.description(), timestep)
            scene = estimator.estimate(timestep)
            assert scene.state == expected
            assert set(scene.box_cells) == expected.boxes
            np.testing.assert_allclose(scene.box_xy, env.task.box_positions())


def test_rounding_rule_keeps_the_walker_off_boxes_and_rejects_two_boxes_in_a_cell():
    env = envs.load("mujoban/level1", seed=0, **NO_CAMERAS)
    description = env.description()
    walls, targets = frozenset({(0, 0)}), frozenset({(5, 5)})
    box = description.cell_centre(4, 4)
    state, cells = rounded_state(description, walls, targets, [box], box, previous_player=(4, 3))
    assert cells == ((4, 4),) and state.player == (4, 3)
    with pytest.raises(EstimationError, match="before any estimate"):
        rounded_state(description, walls, targets, [box], box)
    with pytest.raises(EstimationError, match="two boxes"):
        rounded_state(description, walls, targets, [box, np.add(box, 0.2)], (0.0, 0.0))
    with pytest.raises(EstimationError, match="wall"):
        rounded_state(description, walls, targets, [description.cell_centre(0, 0)], box)


def test_oracle_and_entity_layer_follow_a_pushed_box():
    level = Level.from_text("#######\n#     #\n# @$ .#\n#     #\n#######")
    env = Environment(
        Mujoban(
            sources.FixedLevels([level]), max_boxes=1, randomize_appearance=False, **NO_CAMERAS
        ),
        seed=0,
    )
    timestep = env.reset()
    grid, layer = OracleEstimator(env), EntityLayerEstimator(env)
    grid.reset(env.description(), timestep)
    layer.reset(env.description(), timestep)
    before = grid.estimate(timestep).state
    box = next(iter(before.boxes))
    seen = push_box(env, box, (0, 1))
    after_grid, after_layer = grid.estimate(seen[-1]).state, layer.estimate(seen[-1]).state
    assert after_grid == after_layer
    assert after_grid.boxes == frozenset({(box[0], box[1] + 1)})


def test_board_estimator_replays_the_game_record():
    env = envs.load("mujoxo/optimal", seed=0, front_camera=None)
    timestep = env.reset()
    env.task.play_moves([4, 0, 8, 2])
    timestep = env.step(np.zeros(env.action_spec().shape))
    estimator = BoardEstimator()
    assert not estimator.privileged
    estimator.reset(env.description(), timestep)
    scene = estimator.estimate(timestep)
    state = scene.state
    assert list(state.history()) == [4, 0, 8, 2] and str(state) == str(env.task.state)
    assert scene.moves == (4, 0, 8, 2)
    np.testing.assert_array_equal(scene.qpos, timestep.observation["arm/joints_pos"])
    forged = dict(timestep.observation)
    forged["board_state"] = np.roll(forged["board_state"], 1, axis=0)
    with pytest.raises(EstimationError):
        estimator.estimate(timestep._replace(observation=forged))
