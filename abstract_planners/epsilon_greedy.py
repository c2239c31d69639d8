"""`EpsilonGreedy`: a planner that sometimes plays a random legal move instead.

The paper's opponents are made weaker this way (e.g. GNU Go or minimax playing
a random move with probability epsilon).
"""

from __future__ import annotations

import math
import numbers

import numpy as np

from abstract_planners.base import Planner, Subgoal
from abstract_planners.board_random import check_decision_state

__all__ = ["EpsilonGreedy"]


def _derived_seed(seed: int) -> int:
    """A seed for the inner planner, distinct from (but fixed by) ``seed``."""
    return int(np.random.SeedSequence([int(seed), 0x65707369]).generate_state(1)[0])


class EpsilonGreedy(Planner):
    """With probability ``epsilon`` a uniformly random legal move, else ``planner.plan``.

    Args:
      planner: the inner planner (any planner on pyspiel states).
      epsilon: the probability of a random move, in [0, 1].
      seed: seeds this wrapper's own randomness (the coin flips and the random
        moves), not the inner planner's.

    One uniform number is drawn per `plan` call whatever ``epsilon`` is, so a
    seeded run is reproducible. ``reset(seed)`` reseeds the wrapper and resets
    the inner planner with a seed derived from ``seed`` (or with None).
    ``close()`` closes the inner planner. The Subgoal's info is the inner
    planner's info (for a greedy move) plus ``"random"``: True/False.

    Raises:
      ValueError: ``epsilon`` is not a number in [0, 1].
    """

    def __init__(self, planner: Planner, epsilon: float, seed: int | None = None):
        if not isinstance(planner, Planner):
            raise TypeError(f"planner must be a Planner, got {type(planner).__name__}")
        # int and float are registered numbers.Real (the run-time test is unchanged); listed
        # so that mypy, which does not know they are Reals, sees the code below as reachable.
        if (
            isinstance(epsilon, bool)
            or not isinstance(epsilon, (int, float, numbers.Real))
            or math.isnan(float(epsilon))
            or not 0.0 <= float(epsilon) <= 1.0
        ):
            raise ValueError(f"epsilon must be a number in the range [0, 1], got {epsilon!r}")
        self.planner = planner
        self.epsilon = float(epsilon)
        self.name = f"{planner.name}-eps{epsilon}"
        self._rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)
            self.planner.reset(_derived_seed(seed))
        else:
            self.planner.reset(None)

    def plan(self, state) -> Subgoal:
        check_decision_state(state, self.name)
        if self._rng.random() < self.epsilon:
            legal = state.legal_actions()
            action = int(legal[self._rng.integers(len(legal))])
            return Subgoal(action, state.child(action), info={"random": True})
        subgoal = self.planner.plan(state)
        info = dict(subgoal.info)
        info["random"] = False
        return Subgoal(subgoal.action, subgoal.state, subgoal.plan, info)

    def close(self) -> None:
        self.planner.close()

    def __repr__(self) -> str:
        return f"EpsilonGreedy({self.planner!r}, epsilon={self.epsilon:g})"
