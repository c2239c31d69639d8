"""The random-planner condition: a uniformly random legal Sokoban move.

This is the baseline planner of the paper's planner comparison: it ignores
the goal and proposes, at every step, one of the legal moves of the current
state (walks and pushes alike) with equal probability.
"""

from __future__ import annotations

import random

from abstract_planners.base import Planner, Subgoal
from abstract_planners.sokoban import SokobanState

__all__ = ["RandomPlanner"]


class RandomPlanner(Planner):
    """Proposes a uniformly random legal move.

    ``plan(state)`` returns ``Subgoal(action=move, state=state.apply(move),
    info={"legal_moves": n})`` with ``move`` drawn uniformly from
    ``state.legal_moves()``. Moves come from a private `random.Random`, so
    equal seeds give equal move sequences; ``reset(seed)`` reseeds it
    (``reset()`` without a seed keeps the current stream).

    Args:
      seed: seed of the random stream (None: seeded from the OS).
    """

    name = "random"

    def __init__(self, seed: int | None = None) -> None:
        self.seed = seed
        self._rng = random.Random(seed)

    def __repr__(self) -> str:
        return f"RandomPlanner(seed={self.seed!r})"

    def reset(self, seed: int | None = None) -> None:
        """Reseeds the move stream when ``seed`` is given."""
        if seed is not None:
            self.seed = seed
            self._rng = random.Random(seed)

    def plan(self, state) -> Subgoal:
        """A uniformly random legal move from ``state`` and the state it reaches.

        Raises:
          ValueError: if ``state`` is solved (the episode is over) or the
            player has no legal move.
        """
        if not isinstance(state, SokobanState):
            state = SokobanState.from_level(state)
        if state.is_solved():
            raise ValueError("the state is already solved: there is nothing to plan")
        moves = state.legal_moves()
        if not moves:
            raise ValueError(f"the player at {state.player} has no legal move")
        move = moves[self._rng.randrange(len(moves))]
        return Subgoal(action=move, state=state.apply(move), info={"legal_moves": len(moves)})
