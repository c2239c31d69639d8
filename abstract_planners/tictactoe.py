"""`MinimaxPlanner`: perfect tic-tac-toe play by exact, memoised minimax."""

from __future__ import annotations

import numpy as np

from abstract_planners.base import Planner, Subgoal
from abstract_planners.board_random import check_decision_state

__all__ = ["MinimaxPlanner", "minimax_value", "action_values"]

# Game value for the player to move, keyed by the board text (str(state)),
# which fixes the mover and whether the game is over. Pure, so shared by all
# planners of the process; the whole game has 4,520 non-terminal positions.
_VALUES: dict[str, int] = {}


def _check_tictactoe(state, who: str) -> None:
    check_decision_state(state, who)
    short_name = state.get_game().get_type().short_name
    if short_name != "tic_tac_toe":
        raise ValueError(f"{who} plans tic_tac_toe states, got a {short_name!r} state")


def _outcome_after(state, action: int, mover: int) -> int:
    """Value for ``mover`` of playing ``action`` in ``state``, under perfect play after."""
    child = state.child(action)
    if child.is_terminal():
        return int(round(child.returns()[mover]))
    return -minimax_value(child)


def minimax_value(state) -> int:
    """The tic-tac-toe game value (+1 win, 0 draw, -1 loss) for the player to move.

    ``state`` must not be terminal. Memoised for the whole process.
    """
    key = str(state)
    value = _VALUES.get(key)
    if value is None:
        mover = state.current_player()
        value = max(_outcome_after(state, a, mover) for a in state.legal_actions())
        _VALUES[key] = value
    return value


def action_values(state) -> dict[int, int]:
    """Minimax value of every legal action for the player to move (+1/0/-1)."""
    _check_tictactoe(state, "minimax")
    mover = state.current_player()
    return {int(a): _outcome_after(state, a, mover) for a in state.legal_actions()}


class MinimaxPlanner(Planner):
    """Plays a minimax-optimal tic-tac-toe move, uniformly among the optimal ones.

    Ties between equally optimal moves are broken with
    ``np.random.default_rng(seed)`` (reseeded by ``reset(seed)``), so the
    planner is perfect but not predictable. The choice is drawn once per
    position and episode: asking again about the same position before the
    next ``reset`` (as the option layer does when a touch is cut off at
    ``T_abs`` and re-planned) returns the same move, so a physical agent plays
    the same move distribution as the abstract one.

    Subgoal info: ``"value"`` (game value for the mover, +1/0/-1) and
    ``"optimal_actions"`` (the tied best actions, sorted).

    Raises (from plan):
      ValueError: a terminal state or a state of another game.
    """

    name = "minimax"

    def __init__(self, seed: int | None = None):
        self._rng = np.random.default_rng(seed)
        self._chosen: dict[str, int] = {}

    def reset(self, seed: int | None = None) -> None:
        self._chosen.clear()
        if seed is not None:
            self._rng = np.random.default_rng(seed)

    def plan(self, state) -> Subgoal:
        _check_tictactoe(state, self.name)
        values = action_values(state)
        best = max(values.values())
        optimal = sorted(a for a, v in values.items() if v == best)
        key = str(state)
        action = self._chosen.get(key)
        if action is None:
            action = self._chosen[key] = optimal[int(self._rng.integers(len(optimal)))]
        return Subgoal(
            action, state.child(action), info={"value": best, "optimal_actions": tuple(optimal)}
        )

    def __repr__(self) -> str:
        return "MinimaxPlanner()"
