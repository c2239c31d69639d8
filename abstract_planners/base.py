"""The `Planner` role: abstract state in, `Subgoal` out.

Every planner in this package, and every environment opponent (an opponent is
a planner playing the other side), follows one contract:

* ``reset(seed=None)`` starts a new episode (clears caches tied to the last
  game, reseeds random choices when ``seed`` is given);
* ``plan(state) -> Subgoal``: the next abstract transition to make from
  ``state``. ``Subgoal.action`` is the abstract action (a Sokoban move letter,
  an OpenSpiel action id) and ``Subgoal.state`` the abstract state it reaches;
  ``Subgoal.plan`` may carry the rest of a longer plan when the planner
  computed one (the Sokoban solver does), so callers can skip replanning
  while the world follows it;
* ``close()`` frees external resources (a GNU Go subprocess); planners are
  also context managers.

Abstract states are game-specific: `abstract_planners.sokoban.SokobanState`
for Sokoban, an OpenSpiel ``pyspiel.State`` for tic-tac-toe and Go (the
planner never mutates the state it is given).

Errors: `NoPlanError` when a planner proves there is no plan or exhausts its
budget (the caller decides what to do); `ValueError` for a state the planner
cannot handle (a finished game, the wrong game).
"""

from __future__ import annotations

import abc
from dataclasses import dataclass, field
from typing import Any


class PlannerError(Exception):
    """Base class of planner errors."""


class NoPlanError(PlannerError):
    """The planner found no plan: the state is unsolvable or the budget ran out.

    Attributes:
      reason: ``"unsolvable"`` (proved) or ``"budget"`` (gave up).
    """

    def __init__(self, message: str, *, reason: str):
        super().__init__(message)
        self.reason = reason

    def __reduce__(self):
        return (_rebuild_no_plan_error, (str(self), self.reason))


def _rebuild_no_plan_error(message: str, reason: str) -> "NoPlanError":
    return NoPlanError(message, reason=reason)


@dataclass(frozen=True)
class Subgoal:
    """One abstract transition proposed by a planner.

    Attributes:
      action: the abstract action to take from the planned-from state.
      state: the abstract state that ``action`` reaches.
      plan: the remaining actions after ``action`` when the planner computed a
        longer plan (empty otherwise); replaying ``(action, *plan)`` from the
        planned-from state reaches the planner's goal.
      info: planner statistics (nodes expanded, milliseconds, value, ...).
    """

    action: Any
    state: Any
    plan: tuple = ()
    info: dict = field(default_factory=dict, compare=False, hash=False)


class Planner(abc.ABC):
    """Proposes the next abstract transition. See the module docstring."""

    #: Short name used by CLIs and tables (``"sokoban-solver"``, ``"gnugo"``).
    name: str = "planner"

    def reset(self, seed: int | None = None) -> None:
        """Starts a new episode; reseeds the planner's randomness if given."""

    @abc.abstractmethod
    def plan(self, state) -> Subgoal:
        """The next transition from ``state``.

        Raises:
          NoPlanError: no plan exists or none was found within the budget.
          ValueError: ``state`` is terminal or not a state of this planner's game.
        """

    def close(self) -> None:
        """Frees external resources. Idempotent."""

    def __enter__(self):
        return self

    def __exit__(self, *exc_info) -> None:
        self.close()

    def __repr__(self) -> str:
        return f"{type(self).__name__}()"
