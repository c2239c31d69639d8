"""`RandomMovePlanner`: a uniformly random legal move of any OpenSpiel game."""

from __future__ import annotations

import numpy as np

from abstract_planners.base import Planner, Subgoal

__all__ = ["RandomMovePlanner", "check_decision_state"]


def check_decision_state(state, who: str) -> None:
    """Raises ValueError unless ``state`` is a pyspiel state where a player must move.

    Args:
      state: the state to check.
      who: the planner's name, for the message.
    """
    if not (hasattr(state, "legal_actions") and hasattr(state, "is_terminal")):
        raise ValueError(f"{who} plans on OpenSpiel (pyspiel) states, got {type(state).__name__}")
    if state.is_terminal():
        raise ValueError(f"{who}: the game is over (terminal state), there is no move to plan")
    if state.is_chance_node() or state.is_simultaneous_node():
        raise ValueError(
            f"{who}: plans only where one player must move, not at chance or simultaneous nodes"
        )


class RandomMovePlanner(Planner):
    """Picks a uniformly random legal action for the player to move.

    Works for any turn-based pyspiel state (tic-tac-toe, Go, ...). The
    randomness comes from ``np.random.default_rng(seed)``; `reset` reseeds it
    when given a seed.

    Subgoal info: ``{"num_legal": number of legal actions}``.
    """

    name = "random"

    def __init__(self, seed: int | None = None):
        self._rng = np.random.default_rng(seed)

    def reset(self, seed: int | None = None) -> None:
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def plan(self, state) -> Subgoal:
        check_decision_state(state, self.name)
        legal = state.legal_actions()
        action = int(legal[self._rng.integers(len(legal))])
        return Subgoal(action, state.child(action), info={"num_legal": len(legal)})

    def __repr__(self) -> str:
        return "RandomMovePlanner()"
