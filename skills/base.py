"""The `Skill` role: a subgoal in, motor actions out, until success or failure.

A skill is a closed-loop controller for one kind of body:

* ``reset(env, subgoal, state)`` starts executing a planner's `Subgoal` from
  the abstract ``state`` it was planned from, in ``env`` (an
  `envs.core.Environment`; skills read the task's accessors, e.g. the
  walker's pose or the arm's pinch site, and never change the simulation);
* ``act(timestep) -> action`` returns the next action for ``env.step`` and
  updates ``status``;
* ``status`` is `Status.RUNNING` until the skill reaches the subgoal
  (`Status.SUCCESS`) or gives up (`Status.FAILURE`: stuck, blocked, out of
  reach). The option layer (`hier_agents.option_layer`) also cuts a skill
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
    def reset(self, env, subgoal, state) -> None:
        """Starts executing ``subgoal`` (planned from ``state``) in ``env``."""

    @abc.abstractmethod
    def act(self, timestep) -> np.ndarray:
        """The next action; updates ``status``."""

    def _fail(self, reason: str) -> None:
        self.status = Status.FAILURE
        self.failure_reason = reason

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
