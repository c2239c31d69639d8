"""Stable-Baselines3 algorithms trained on the gymnasium environments.

    from hier_agents.baselines.sb3 import Sb3Config, train
    config = Sb3Config.from_options("mujoban/level1", {"algo": "PPO", "frames": 4096})
    counters = train(config)          # {"frames": ..., "wall_s": ..., "cpu_s": ...}

`config` holds `Sb3Config` (the one way in, from argv or a comparison
spec's ``sb3`` table); `trainer` the training loop (`train`: run directory,
kept checkpoints ``LOGDIR/checkpoints/frames-B.zip``, resuming); the
``sb3:PATH`` agent kind (`hier_agents.agents.sb3`) plays what it saves;
``python -m hier_agents.baselines.sb3`` is the command.
"""

from hier_agents.baselines.sb3.config import Sb3Config
from hier_agents.baselines.sb3.trainer import train

__all__ = ["Sb3Config", "train"]
