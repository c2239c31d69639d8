"""Tiny environments and networks shared by the PPO and run-directory tests."""

from __future__ import annotations

import gymnasium as gym
import numpy as np
import torch
from torch import nn

from hier_agents.learning import ppo


class Target(gym.Env):
    """One-step episodes: observe a target x in [-1, 1], act a, reward -(a - x)^2."""

    observation_space = gym.spaces.Box(-1.0, 1.0, (1,), np.float32)
    action_space = gym.spaces.Box(-3.0, 3.0, (1,), np.float32)

    def reset(self, *, seed=None, options=None):
        super().reset(seed=seed)
        self.x = self.np_random.uniform(-1, 1, size=1).astype(np.float32)
        return self.x.copy(), {}

    def step(self, action):
        return self.x.copy(), -float((np.asarray(action)[0] - self.x[0]) ** 2), True, False, {}


class Gaussian(nn.Module):
    def __init__(self):
        super().__init__()
        self.mean, self.v = nn.Linear(1, 1), nn.Linear(1, 1)
        self.log_std = nn.Parameter(torch.zeros(1))

    def policy_dist(self, obs, mask):
        return ppo.diag_gaussian(self.mean(obs), self.log_std)

    def value(self, obs):
        return self.v(obs).squeeze(-1)
