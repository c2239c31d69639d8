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
from hier_agents.estimators import (BoardEstimator, EntityLayerEstimator, EstimationError,
                                    GridRoundingEstimator)

NO_CAMERAS = {"top_camera": None, "egocentric_camera": None}


def test_mujoban_estimators_read_the_level_at_reset():
    path = BOXOBAN_DIR / "medium-valid-000.txt"
    env = envs.load("mujoban/level5", seed=0, levels=str(path), **NO_CAMERAS)
    for level in read_levels(path)[:3]:
        timestep = env.reset()
        expected = SokobanState.from_level(level)
        for estimator in (EntityLayerEstimator(), GridRoundingEstimator()):
            estimator.reset(env, timestep)
            assert estimator.estimate(env, timestep) == expected


def test_grid_rounding_follows_a_pushed_box():
    level = Level.from_text("#######\n#     #\n# @$ .#\n#     #\n#######")
    env = Environment(Mujoban(sources.FixedLevels([level]), max_boxes=1,
                              randomize_appearance=False, **NO_CAMERAS), seed=0)
    timestep = env.reset()
    grid, layer = GridRoundingEstimator(), EntityLayerEstimator()
    grid.reset(env, timestep)
    before = grid.estimate(env, timestep)
    box = next(iter(before.boxes))
    seen = push_box(env, box, (0, 1))
    after_grid, after_layer = grid.estimate(env, seen[-1]), layer.estimate(env, seen[-1])
    assert after_grid == after_layer
    assert after_grid.boxes == frozenset({(box[0], box[1] + 1)})


def test_board_estimator_replays_the_game_record():
    env = envs.load("mujoxo/optimal", seed=0, front_camera=None)
    timestep = env.reset()
    env.task.play_moves([4, 0, 8, 2])
    timestep = env.step(np.zeros(env.action_spec().shape))
    estimator = BoardEstimator()
    estimator.reset(env, timestep)
    state = estimator.estimate(env, timestep)
    assert list(state.history()) == [4, 0, 8, 2] and str(state) == str(env.task.state)
    forged = dict(timestep.observation)
    forged["board_state"] = np.roll(forged["board_state"], 1, axis=0)
    with pytest.raises(EstimationError):
        estimator.estimate(env, timestep._replace(observation=forged))
