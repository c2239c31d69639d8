"""`BoardEstimator` (``board``): board-game scenes (MuJoXO, MuJoGo, MuJoBoard)
from observations.

The game comes from the ``move_history`` observation (the game record)
replayed in OpenSpiel and checked against the ``board_state`` markers, seen
from the side the ``agent_player`` observation names; a move game's half
move from ``selected_point``; the arm from its joint observations
(``arm/joints_pos``, ``arm/joints_vel``, which are the qpos and qvel of the
arm's own model, `envs.description.ArmDescription`). Observation-only.
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.boards.games import BoardGame
from hier_agents.estimators.base import EstimationError, Estimator
from skills.scene import ArmScene


def scalar(obs, key: str, default: int) -> int:
    """The integer of a one-element observation, or ``default`` without it."""
    value = obs.get(key)
    return default if value is None else int(np.asarray(value).reshape(-1)[0])


class BoardEstimator(Estimator):
    """The game record replayed in OpenSpiel, and the arm's joints."""

    name = "board"

    def __init__(self) -> None:
        # (game, its loaded OpenSpiel game) by game, and the current episode's.
        self._games: dict[BoardGame, tuple[BoardGame, Any]] = {}
        self._game: tuple[BoardGame, Any] | None = None

    def reset(self, description, timestep) -> None:
        game = BoardGame.from_description(description)
        if game not in self._games:
            self._games[game] = (game, game.load())
        self._game = self._games[game]

    def estimate(self, timestep) -> ArmScene:
        if self._game is None:
            raise RuntimeError("BoardEstimator.estimate called before reset")
        game, spiel = self._game
        obs = timestep.observation
        agent = scalar(obs, "agent_player", 0)
        history = np.asarray(obs["move_history"])
        end = int(np.argmax(history < 0)) if (history < 0).any() else len(history)
        played = history[:end]
        state = spiel.new_initial_state()
        for action in played:
            state.apply_action(int(action))
        if not np.array_equal(game.board_planes(state, agent), obs["board_state"]):
            raise EstimationError("move_history and board_state disagree")
        return ArmScene(
            state=state,
            moves=tuple(int(a) for a in played),
            qpos=np.array(obs["arm/joints_pos"], float),
            qvel=np.array(obs["arm/joints_vel"], float),
            selected=scalar(obs, "selected_point", -1),
            agent=agent,
        )
