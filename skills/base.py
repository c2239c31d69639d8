"""The `Skill` role: a subgoal in, motor actions out, until success or failure.

A skill is a closed-loop controller for one kind of body:

* ``reset(description, subgoal, scene)`` starts executing a planner's
  `Subgoal` from the scene it was planned from (``scene.state`` is the
  abstract state); ``description`` is the task's public description
  (`envs.description`);
* ``act(timestep, scene) -> action`` returns the next action for
  ``env.step`` from the current timestep and the estimator's scene for it
  (`skills.scene`), and updates ``status``;
* ``hold() -> action`` keeps the body still (used while no estimate can be
  made);
* ``forget_history()`` drops what the skill carries between subgoals (the
  agent calls it at every episode start, so an episode plays the same
  whatever the episodes before it).

Skills see the subgoal, the scene estimate, the timestep's observations and
the public description, never the simulator (the observation boundary).
* ``status`` is `Status.RUNNING` until the skill reaches the subgoal
  (`Status.SUCCESS`) or gives up (`Status.FAILURE`: stuck, blocked, out of
  reach). The option layer (`hier_agents.modular.agent`) also cuts a skill
  off after ``T_abs`` control steps and re-estimates.

Skills take a seed or a generator for any randomness and keep no state
between ``reset`` calls beyond what they document.
"""

from __future__ import annotations

import abc
import enum

import numpy as np


class Status(enum.Enum):
    """Where a skill stands with its current subgoal."""

    RUNNING = "running"
    SUCCESS = "success"
    FAILURE = "failure"


class Skill(abc.ABC):
    """Turns one subgoal into actions. See the module docstring."""

    #: Short name used by CLIs and tables (``"ball-push"``, ``"arm-touch"``).
    name: str = "skill"

    def __init__(self) -> None:
        self.status = Status.RUNNING
        #: Why the last subgoal failed, for logs and tables.
        self.failure_reason: str | None = None

    @abc.abstractmethod
    def reset(self, description, subgoal, scene) -> None:
        """Starts executing ``subgoal`` (planned from ``scene``)."""

    @abc.abstractmethod
    def act(self, timestep, scene) -> np.ndarray:
        """The next action; updates ``status``."""

    @abc.abstractmethod
    def hold(self) -> np.ndarray:
        """An action that keeps the body still."""

    def forget_history(self) -> None:
        """Drops what the skill carries from one subgoal to the next (rates,
        filters, back-off counts): called when it did not see the frames
        before its next ``reset`` (a new episode or level, a scripted
        fast-forward), so that an episode plays the same whatever came
        before it. No-op by default."""

    def close(self) -> None:
        """Frees external resources (none by default). Idempotent."""

    def _fail(self, reason: str) -> None:
        self.status = Status.FAILURE
        self.failure_reason = reason

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
