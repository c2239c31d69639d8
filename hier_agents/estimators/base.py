"""The `Estimator` role: observations in, a scene estimate out.

An estimator is told the task's public description at every episode start
(``reset(description, timestep)``) and turns each timestep into a scene
(``estimate(timestep)``): `skills.scene.BallScene` for MuJoBan,
`skills.scene.ArmScene` for the board games; ``scene.state`` is the
planner's abstract state. Observation-only estimators use nothing else.

An estimator that reads the simulator or the ground truth the environment
computes from it (``full_entity_layer``, ``pixel_layer``) sets
``privileged = True``; run tables and JSON say so.
"""

from __future__ import annotations

import abc


class EstimationError(RuntimeError):
    """The observation does not describe a consistent scene (e.g. two boxes
    in one cell, the walker not found). The agent holds still and estimates
    again on the next timestep."""


class Estimator(abc.ABC):
    """Turns observations into a scene estimate. See the module docstring."""

    #: Short name for CLIs, tables and JSON.
    name = "estimator"
    #: True when the estimate uses more than a robot would observe.
    privileged = False
    #: `envs.load` overrides the estimator needs (e.g. a camera's frame size).
    env_overrides: dict = {}

    def reset(self, description, timestep) -> None:
        """Called with the public task description and the first timestep of
        every episode."""

    @abc.abstractmethod
    def estimate(self, timestep):
        """The scene now. Raises `EstimationError` when it cannot be made."""

    def close(self) -> None:
        """Frees external resources (none by default). Idempotent."""

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
