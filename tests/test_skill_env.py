"""Skill environments (`hier_agents.learning.skill_env.SkillEnv`) with the ball spec."""

import dataclasses

import gymnasium
import numpy as np
import pytest

from hier_agents.learning.skill_env import SkillEnv
from hier_agents.learning.skills.ball import BALL_SPEC, BallSceneSource
from skills.base import Status


def _env(
    sources=("mujoban/level2-pegs", "mujoban/level1"),
    seed=0,
    estimator=None,
    t_abs=None,
    **source_kw,
):
    """A ball skill environment drawing scenes from ``sources`` only."""
    spec = dataclasses.replace(
        BALL_SPEC, scenes=lambda s, est: BallSceneSource(s, est, sources=sources, **source_kw)
    )
    return SkillEnv(spec, seed=seed, estimator=estimator, t_abs=t_abs)


def test_gymnasium_check_env():
    from gymnasium.utils.env_checker import check_env

    env = _env()
    check_env(env, skip_render_check=True)
    env.close()


def test_stable_baselines3_check_env():
    from stable_baselines3.common.env_checker import check_env

    env = _env()
    check_env(env, warn=True)
    env.close()


def test_registered():
    import hier_agents.learning.skill_env  # noqa: F401  (registers the id)

    env = gymnasium.make("options/ball-push", seed=1)
    obs, info = env.reset(seed=1)
    assert env.observation_space.contains(obs)
    assert info["status"] == "running"
    env.close()


def test_seeded_resets_repeat():
    a, b = _env(), _env()
    for seed in (3, 4):
        oa, _ = a.reset(seed=seed)
        ob, _ = b.reset(seed=seed)
        np.testing.assert_array_equal(oa, ob)
        for _ in range(5):
            oa = a.step([0.3, -0.2])[0]
            ob = b.step([0.3, -0.2])[0]
        np.testing.assert_array_equal(oa, ob)


def test_reward_exactly_when_the_subgoal_is_reached():
    """The scripted controller's actions (``info["expert_action"]``) drive
    options; the success reward comes on the step at which the option is
    reached, then, and only then, and the estimate then equals the
    subgoal's abstract state."""
    env = _env(sources=("mujoban/level3-pegs", "boxoban/unfiltered-valid-000"), seed=5)
    successes = 0
    for _ in range(6):
        obs, info = env.reset()
        done = False
        while not done:
            obs, reward, terminated, truncated, info = env.step(info["expert_action"])
            done = terminated or truncated
            reached = info["status"] == "reached"
            assert reward == pytest.approx(
                BALL_SPEC.step_cost
                + (1.0 if reached else 0.0)
                - (1.0 if info["status"] == "failed" and reward < -0.5 else 0.0)
            )
            assert terminated == (info["status"] in ("reached", "failed"))
            if reached:
                start = env._start
                scene = start.estimator.estimate(start.timestep)
                assert frozenset(scene.box_cells) == start.subgoal.state.boxes
                if not start.timestep.last():  # the push that solves a level ends it early
                    assert env.skill.status is Status.SUCCESS
                    assert scene.state.player == start.subgoal.state.player
        assert info["is_success"] == (info["status"] == "reached")
        successes += info["is_success"]
    assert successes >= 5


def test_disturbing_boxes_is_penalised():
    env = _env(sources=("mujoban/level5",), seed=2)
    env.reset()
    env.skill._fail("box disturbed: box 1 moved 0.3 m but should not have")
    # The next step sees the failure and pays the penalty.
    _, reward, terminated, _, info = env.step([0.0, 0.0])
    assert terminated and info["status"] == "failed"
    assert reward == pytest.approx(-1.0 + BALL_SPEC.step_cost)


def test_truncated_at_t_abs():
    env = _env(t_abs=5)
    env.reset()
    for k in range(5):
        _, _, terminated, truncated, info = env.step([0.0, 0.0])
        assert not terminated
        assert truncated == (k == 4)


def test_camera_estimator_is_observation_only():
    env = _env(sources=("mujoban/level1",), estimator="camera", seed=3, max_skip=0)
    assert not env.privileged
    obs, info = env.reset()
    done = False
    while not done:
        obs, _, terminated, truncated, info = env.step(info["expert_action"])
        done = terminated or truncated
    assert info["is_success"]
    env.close()


def test_stable_baselines3_ppo_runs():
    from stable_baselines3 import PPO

    env = _env(sources=("mujoban/level1",), t_abs=40)
    model = PPO("MlpPolicy", env, n_steps=64, batch_size=32, n_epochs=2, seed=0, device="cpu")
    model.learn(total_timesteps=192)
    assert model.num_timesteps >= 192
    env.close()
