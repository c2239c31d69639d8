"""The learned arm touch skill (`skills.learned.arm`) and its scene source."""

from __future__ import annotations

import numpy as np
import pytest

import envs
from abstract_planners.base import Subgoal
from hier_agents.estimators import BoardEstimator
from hier_agents.learning.skill_spec import OptionStart, spec
from hier_agents.learning.skills.arm import ArmSceneSource
from skills.base import Status
from skills.learned.arm import ACTION_DIM, FEATURES, POLICY_PATH, LearnedArmSkill
from skills.learned.policy import load_policy
from skills.scene import ArmScene


def _subgoal(state, action):
    child = state.clone()
    child.apply_action(action)
    return Subgoal(action=action, state=child)


@pytest.fixture
def xo():
    """A fresh environment per test: its random arm poses do not depend on the
    tests that ran before (the order differs between workers)."""
    env = envs.load("mujoxo/optimal", seed=3, **envs.no_cameras("mujoxo/optimal"))
    yield env
    env.close()


def test_checkpoint_loads_with_the_skills_features():
    assert POLICY_PATH.is_file()
    assert POLICY_PATH.stat().st_size < 200_000
    policy = load_policy(POLICY_PATH, FEATURES)
    assert policy.obs_dim == len(FEATURES) and policy.action_dim == ACTION_DIM
    assert policy.meta.get("sim_steps", 0) > 0
    assert policy.meta["trained_with"] == "hier_agents.learning.train_skill"  # the shared trainer
    assert policy.meta["command"].startswith("python -m hier_agents.learning.train_skill arm")
    out = policy(np.zeros(len(FEATURES)))
    assert out.shape == (ACTION_DIM,) and np.all(np.isfinite(out))
    with pytest.raises(ValueError):
        load_policy(POLICY_PATH, FEATURES[:-1])
    skill = LearnedArmSkill()
    assert skill.training_frames > 0 and not skill.labels


def test_spec_names_the_skill():
    arm = spec("arm")
    assert arm.skill_name == "learned-arm" and arm.checkpoint == POLICY_PATH
    assert arm.make_skill(None).record_only


@pytest.mark.parametrize("action", [4, 0, 8])
def test_learned_skill_touches_the_requested_point(xo, action):
    estimator = BoardEstimator()
    timestep = xo.reset()
    description = xo.description()
    estimator.reset(description, timestep)
    scene = estimator.estimate(timestep)
    skill = LearnedArmSkill()
    skill.reset(description, _subgoal(scene.state, action), scene)
    for _ in range(50):
        command = skill.act(timestep, scene)
        if skill.status is not Status.RUNNING:
            break
        assert command.shape == (9,)
        timestep = xo.step(command)
        scene = estimator.estimate(timestep)
    else:
        skill.act(timestep, scene)
    assert skill.status is Status.SUCCESS, skill.failure_reason
    assert scene.moves[0] == action


def test_record_only_holds_and_records_features_and_teacher_action(xo):
    estimator = BoardEstimator()
    timestep = xo.reset()
    description = xo.description()
    estimator.reset(description, timestep)
    scene = estimator.estimate(timestep)
    skill = LearnedArmSkill(record_only=True)
    assert skill.record_only and skill.labels
    skill.reset(description, _subgoal(scene.state, 2), scene)
    for _ in range(3):
        command = skill.act(timestep, scene)
        np.testing.assert_array_equal(command, skill.hold())
        features, label = skill.features, skill.teacher_action
        assert features.shape == (len(FEATURES),) and features.dtype == np.float32
        assert np.all(np.isfinite(features))
        assert label is not None and label.shape == (ACTION_DIM,)
        assert np.all(np.abs(label) <= 1.0)
        # The teacher's own command, through the fixed map.
        np.testing.assert_allclose(skill.env_action(label)[6:], skill.hold()[6:])
        timestep = xo.step(skill.env_action(label))
        scene = estimator.estimate(timestep)
    assert skill.status is Status.RUNNING


def test_illegal_subgoal_fails_at_reset(xo):
    estimator = BoardEstimator()
    timestep = xo.reset()
    estimator.reset(xo.description(), timestep)
    scene = estimator.estimate(timestep)
    skill = LearnedArmSkill(record_only=True)
    for subgoal in (Subgoal(action=99, state=None), Subgoal(action=4, state=None)):
        if subgoal.action == 4:  # a legal point, but not in this (terminal-free) state copy
            state = scene.state.clone()
            state.apply_action(4)
            scene = ArmScene(state=state, moves=scene.moves, qpos=scene.qpos, qvel=scene.qvel)
        skill.reset(xo.description(), subgoal, scene)
        assert skill.status is Status.FAILURE and skill.failure_reason.startswith("illegal")
        np.testing.assert_array_equal(skill.act(timestep, scene), skill.hold())


def test_scene_source_yields_valid_option_starts():
    source = ArmSceneSource(5, sources=("mujoxo/mixture",), weights=(1.0,))
    rng = np.random.default_rng(0)
    try:
        seen = 0
        for _ in range(4):
            start = source.start(rng)
            if start is None:
                continue
            seen += 1
            assert isinstance(start, OptionStart) and start.source == "mujoxo/mixture"
            assert isinstance(start.scene, ArmScene)
            assert int(start.subgoal.action) in start.scene.state.legal_actions()
            assert start.description.game == "tic_tac_toe"
            # Drive it with the teacher for a few steps; the source counts them.
            skill = LearnedArmSkill("teacher")
            skill.reset(start.description, start.subgoal, start.scene)
            before = source.sim_steps
            timestep, scene = start.timestep, start.scene
            for _ in range(5):
                command = skill.act(timestep, scene)
                if skill.status is not Status.RUNNING or timestep.last():
                    break
                timestep = start.env.step(command)
                scene = start.estimator.estimate(timestep)
            assert source.sim_steps > before
            source.end(True)
        assert seen >= 3
    finally:
        source.close()
