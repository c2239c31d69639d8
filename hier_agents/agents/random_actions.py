"""`RandomAgent`: uniformly random actions, the floor every trained agent must clear.

Each action component is drawn independently and uniformly from its bounds,
a new draw every ``hold`` control steps. In MuJoBan, holding a draw for a
while rolls the ball further and solves more levels than drawing at every
step; compare against the better of the two.
"""

from __future__ import annotations

import numpy as np

from hier_agents.agents.base import HeldAction
from hier_agents.modular.agent import OptionStats

__all__ = ["RandomAgent"]

#: Mixed into the seed of the action draws (distinct from the environment's).
_ACTIONS = 0x61637473


class RandomAgent:
    """Random actions within ``action_spec``'s bounds, each held ``hold``
    control steps (the `hier_agents.agents.base.Agent` contract). An
    episode's draws come from its seed alone."""

    privileged = False
    training_frames = 0
    estimates = False
    scene = None
    gave_up = None

    def __init__(self, action_spec, hold: int = 1):
        if int(hold) < 1:
            raise ValueError(f"hold must be >= 1 control steps, got {hold!r}")
        self.hold = int(hold)
        self._held = HeldAction(self.hold)
        self._low = np.broadcast_to(action_spec.minimum, action_spec.shape)
        self._high = np.broadcast_to(action_spec.maximum, action_spec.shape)
        self.episode_stats = OptionStats()
        self._rng = np.random.default_rng(_ACTIONS)

    def reset(self, description, timestep, seed: int | None = None) -> None:
        self._rng = np.random.default_rng([seed, _ACTIONS] if seed is not None else None)
        self._held.reset()

    def act(self, timestep) -> np.ndarray:
        held = self._held.next()
        if held is not None:
            return held
        return self._held.hold(self._rng.uniform(self._low, self._high))

    def end_episode(self, timestep) -> None:
        pass

    def close(self) -> None:
        pass
