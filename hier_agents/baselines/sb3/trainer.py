"""`train`: a Stable-Baselines3 run in a run directory."""

from __future__ import annotations

from hier_agents.baselines.sb3.config import Sb3Config

__all__ = ["train"]


def train(config: Sb3Config) -> dict:
    """Trains (or resumes) ``config``'s run; returns its counters (``frames``,
    ``wall_s``, ``cpu_s``, ...)."""
    raise NotImplementedError
