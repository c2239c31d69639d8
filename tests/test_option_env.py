"""`OptionEnv`: the semi-MDP over options (issue 15, item 3)."""

from __future__ import annotations

import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from abstract_planners.sokoban_solver import SokobanSolverPlanner
from abstract_planners.sokoban import MOVES
from hier_agents.learning.option_env import OptionEnv, encode_sokoban


def _solver_action(env, info):
    subgoal = SokobanSolverPlanner().plan(env.abstract_state)
    move = subgoal.action[0] if isinstance(subgoal.action, tuple) else subgoal.action
    return MOVES.index(move)


def _record_rewards(env) -> list:
    """Records the reward of every control step the simulator takes (OptionEnv
    steps it through the boundary)."""
    rewards = []
    step = env._env.step

    def recording_step(action):
        timestep = step(action)
        rewards.append(float(timestep.reward or 0.0))
        return timestep

    env._env.step = recording_step
    return rewards


def test_gymnasium_check_env_passes_on_mujoban_and_mujoxo():
    for name in ("mujoban/level1", "mujoxo/mixture"):
        env = OptionEnv(name, estimator="oracle" if name.startswith("mujoban") else None, seed=0)
        try:
            check_env(env, skip_render_check=True)
        finally:
            env.close()


def test_durations_add_up_to_the_episode_and_rewards_to_its_return():
    env = OptionEnv("mujoban/level2", seed=3, gamma=1.0)  # observation-only (camera)
    rewards = _record_rewards(env)
    try:
        obs, info = env.reset(seed=3)
        assert obs.shape == env.observation_space.shape and info["steps"] == 0
        total_duration, total_reward, options = 0, 0.0, 0
        while True:
            obs, reward, terminated, truncated, info = env.step(_solver_action(env, info))
            options += 1
            total_duration += info["duration"]
            total_reward += reward
            assert info["status"] in ("success", "failure", "cut off")
            if terminated or truncated:
                break
        assert terminated and env._env.task.solved
        assert total_duration == info["steps"] == len(rewards)
        assert total_reward == pytest.approx(sum(rewards))
        assert options >= 2
    finally:
        env.close()


def test_the_option_reward_is_discounted_per_control_step():
    env = OptionEnv("mujoban/level1", estimator="oracle", seed=0, gamma=0.9)
    rewards = _record_rewards(env)
    try:
        _, info = env.reset(seed=0)
        _, reward, *_ = env.step(_solver_action(env, info))
        assert reward == pytest.approx(sum(0.9**k * r for k, r in enumerate(rewards)))
    finally:
        env.close()


def test_an_illegal_option_holds_for_one_step():
    env = OptionEnv("mujoban/level1", estimator="oracle", seed=0, illegal_penalty=-0.5)
    try:
        _, info = env.reset(seed=0)
        illegal = np.flatnonzero(info["action_mask"] == 0)
        assert illegal.size  # level 1 starts next to a wall
        _, reward, terminated, _, info = env.step(int(illegal[0]))
        assert info["status"] == "illegal" and info["duration"] == 1 and info["steps"] == 1
        assert reward == pytest.approx(-0.5)
        with pytest.raises(ValueError, match="action must be"):
            env.step(7)
    finally:
        env.close()


def test_board_options_are_moves_and_the_opponent_replies():
    env = OptionEnv("mujoxo/mixture", seed=0)
    try:
        obs, info = env.reset(seed=0)
        assert info["action_mask"].sum() == 9
        obs, _, terminated, _, info = env.step(4)  # the centre
        assert info["status"] == "success"
        # Ours and the opponent's reply: two points taken.
        assert info["action_mask"].sum() == 7 and not terminated
        assert "(" in repr(env) or "OptionEnv" in repr(env)
    finally:
        env.close()


def test_sokoban_encoding_planes():
    from abstract_planners.sokoban import SokobanState

    state = SokobanState.from_text("#####\n#@$.#\n#####")
    planes = encode_sokoban(state, (3, 5))
    assert planes.shape == (4, 3, 5)
    assert planes[0].sum() == 12 and planes[1, 1, 3] == 1 and planes[2, 1, 2] == 1
    assert planes[3, 1, 1] == 1


def test_stable_baselines3_trains_on_option_env():
    from stable_baselines3 import PPO

    env = OptionEnv("mujoban/level1", estimator="oracle", seed=0)
    try:
        model = PPO("MlpPolicy", env, n_steps=32, batch_size=16, n_epochs=1, seed=0, device="cpu")
        model.learn(total_timesteps=64)
        action, _ = model.predict(env.reset(seed=1)[0], deterministic=True)
        assert env.action_space.contains(int(action))
    finally:
        env.close()
