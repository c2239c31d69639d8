"""The PPO core (`hier_agents.learning.ppo`): GAE with durations, the rollout
collector's autoreset handling, and learning a known optimum on tiny tasks."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import pytest
import torch
from torch import nn

from hier_agents.learning import ppo
from toy_rl import Gaussian, Target


class OptionChain(gym.Env):
    """Two decisions. Stage 0: option 0 (duration 1) or option 1 (duration 10)
    lead to stage 1 with no reward; option 2 (reward 10) is masked out and must
    never be taken. Stage 1: any action gives 1 and ends the episode. Only the
    discount ``gamma ** duration`` separates options 0 and 1: 0 is optimal."""

    observation_space = gym.spaces.Box(0.0, 1.0, (2,), np.float32)
    action_space = gym.spaces.Discrete(3)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.stage = 0
        return self._obs(), {"action_mask": np.array([1, 1, 0], np.int8), "duration": 0}

    def _obs(self):
        return np.eye(2, dtype=np.float32)[self.stage]

    def step(self, action):
        action = int(action)
        if self.stage == 0:
            if action == 2:
                raise ValueError("a masked action was taken")
            self.stage = 1
            return (
                self._obs(),
                0.0,
                False,
                False,
                {"action_mask": np.ones(3, np.int8), "duration": 1 if action == 0 else 10},
            )
        return self._obs(), 1.0, True, False, {"action_mask": np.ones(3, np.int8), "duration": 1}


class Walk(gym.Env):
    """Observation = steps taken; truncated after 3 steps, each of duration 2."""

    observation_space = gym.spaces.Box(0.0, 10.0, (1,), np.float32)
    action_space = gym.spaces.Discrete(2)

    def reset(self, *, seed=None, options=None):
        self.t = 0
        return np.array([0.0], np.float32), {"duration": 0}

    def step(self, action):
        self.t += 1
        return np.array([self.t], np.float32), 1.0, False, self.t >= 3, {"duration": 2}


class Discrete(nn.Module):
    def __init__(self, obs_dim, actions):
        super().__init__()
        self.pi, self.v = nn.Linear(obs_dim, actions), nn.Linear(obs_dim, 1)

    def policy_dist(self, obs, mask):
        return ppo.masked_categorical(self.pi(obs), mask)

    def value(self, obs):
        return self.v(obs).squeeze(-1)


def test_gae_with_durations_and_a_truncation_matches_a_hand_computation():
    gamma, lam = 0.9, 0.5
    rewards = torch.tensor([[1.0], [0.0], [2.0]])
    values = torch.tensor([[0.5], [0.25], [1.0]])
    durations = torch.tensor([[2.0], [1.0], [3.0]])
    dones = torch.tensor([[0.0], [1.0], [0.0]])  # step 1 ends its episode (truncated)
    bootstrap = torch.tensor([[0.0], [0.7], [0.0]])  # V(final obs) of that episode
    next_value = torch.tensor([3.0])
    adv, returns = ppo.gae(rewards, values, gamma**durations, dones, next_value, lam, bootstrap)
    d2 = 2.0 + 0.9**3 * 3.0 - 1.0
    d1 = 0.0 + 0.9 * 0.7 - 0.25  # the bootstrap, not the next episode's value
    d0 = 1.0 + 0.9**2 * 0.25 - 0.5
    expected = [d0 + 0.9**2 * lam * d1, d1, d2]
    assert adv[:, 0].tolist() == pytest.approx(expected)
    assert torch.allclose(returns, adv + values)


def test_the_collector_handles_same_step_autoreset_durations_and_truncation():
    envs = ppo.make_vector_env([Walk, Walk])
    policy = Discrete(1, 2)
    with torch.no_grad():
        policy.v.weight.fill_(10.0)  # V(obs) = 10 * steps taken
        policy.v.bias.zero_()
    collector = ppo.RolloutCollector(envs, policy, steps=4)
    rollout = collector.collect()
    assert rollout.obs[:, 0, 0].tolist() == [0, 1, 2, 0]  # reset after the third step
    assert rollout.dones[:, 0].tolist() == [0, 0, 1, 0]
    assert rollout.bootstrap[:, 0].tolist() == [0, 0, 30.0, 0]  # V of the final obs (3)
    assert rollout.durations.eq(2).all() and rollout.masks is None
    assert rollout.next_value.tolist() == [10.0, 10.0]
    assert [
        (e.env, e.truncated, e.terminated, e.length, e.duration, e.ret) for e in rollout.episodes
    ] == [(0, True, False, 3, 6.0, 3.0), (1, True, False, 3, 6.0, 3.0)]
    assert rollout.episodes[0].info["duration"] == 2
    envs.close()
    with pytest.raises(ValueError, match="SAME_STEP"):
        ppo.RolloutCollector(gym.vector.SyncVectorEnv([Walk]), policy, steps=1)


@pytest.mark.slow
def test_ppo_learns_the_shorter_option_and_never_takes_a_masked_one():
    torch.manual_seed(0)
    envs = ppo.make_vector_env([OptionChain] * 4)
    policy = Discrete(2, 3)
    cfg = ppo.PPOConfig(gamma=0.9, lam=0.95, lr=0.05, epochs=4, minibatches=2, ent_coef=0.0)
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    collector = ppo.RolloutCollector(envs, policy, steps=16)
    collector.reset(seed=0)
    for _ in range(40):
        rollout, stats = ppo.iteration(collector, optimizer, cfg)
        assert rollout.masks is not None and np.isfinite(stats["policy_loss"])
    envs.close()
    with torch.no_grad():
        probs = policy.policy_dist(torch.tensor([[1.0, 0.0]]), torch.tensor([[1, 1, 0]])).probs[0]
        value = policy.value(torch.tensor([[1.0, 0.0]])).item()
    assert probs[0] > 0.95 and probs[2] == 0.0, probs
    assert value == pytest.approx(0.9, abs=0.1)  # gamma ** 1 * 1


def test_ppo_moves_a_gaussian_policy_onto_a_continuous_target():
    torch.manual_seed(0)
    envs = ppo.make_vector_env([Target] * 8)
    policy = Gaussian()
    cfg = ppo.PPOConfig(gamma=0.99, lr=0.02, epochs=4, minibatches=4, anneal_lr=True, lr_floor=0.1)
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    collector = ppo.RolloutCollector(envs, policy, steps=32)
    collector.reset(seed=1)
    iterations = 60
    for k in range(iterations):
        _, stats = ppo.iteration(collector, optimizer, cfg, fraction_left=1 - k / iterations)
    envs.close()
    assert stats["lr"] == pytest.approx(cfg.lr * max(1 / iterations, 0.1))
    x = torch.linspace(-1, 1, 9)[:, None]
    with torch.no_grad():
        mean = policy.policy_dist(x, None).mean
    assert (mean - x).abs().max() < 0.15, torch.cat([x, mean], 1)
    assert policy.log_std.item() < -0.5  # the std shrank from 1


def test_a_critic_only_update_leaves_the_actor_alone():
    torch.manual_seed(0)
    envs = ppo.make_vector_env([Target] * 2)
    policy = Gaussian()
    actor_before = [p.clone() for p in (policy.mean.weight, policy.mean.bias, policy.log_std)]
    critic_before = policy.v.weight.clone()
    cfg = ppo.PPOConfig(lr=0.01)
    optimizer = torch.optim.Adam(policy.parameters(), lr=cfg.lr)
    collector = ppo.RolloutCollector(envs, policy, steps=8)
    ppo.iteration(collector, optimizer, cfg, actor=False)
    envs.close()
    for before, after in zip(actor_before, (policy.mean.weight, policy.mean.bias, policy.log_std)):
        assert torch.equal(before, after)
    assert not torch.equal(critic_before, policy.v.weight)
