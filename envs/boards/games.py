"""The abstract games behind the board environments, on OpenSpiel.

A `BoardGame` says what the physical task needs from a game: its OpenSpiel
game, the board size, which actions are board points and which is a pass,
how to read a state into one-hot planes, and the agent's reward at the end.
The agent is always OpenSpiel's player 0 (crosses in tic-tac-toe, black in
Go) and always moves first.

Board coordinates: action ``a`` of an N x N board is the point
``(a // N, a % N)``, the layout of OpenSpiel's observation tensors. In Go,
row 0 is GTP row 1 (nearest the arm); in tic-tac-toe row 0 is the row
OpenSpiel prints first (farthest from the arm).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import pyspiel

#: board_state planes.
EMPTY, OWN, OPPONENT = 0, 1, 2
AGENT = 0

GO_SIZES = (5, 19)


@dataclass(frozen=True)
class BoardGame:
    """One game as the physical task sees it.

    Attributes:
      name: ``"tic_tac_toe"`` or ``"go"``.
      size: board side N.
      komi: Go komi (ignored for tic-tac-toe).
      draw_reward: the agent's reward for a drawn game.
    """

    name: str
    size: int
    komi: float = 0.0
    draw_reward: float = 0.5

    def __post_init__(self):
        if self.name == "go":
            if not (isinstance(self.size, (int, np.integer)) and not isinstance(self.size, bool)
                    and GO_SIZES[0] <= self.size <= GO_SIZES[1]):
                raise ValueError(f"board_size must be an integer in {GO_SIZES[0]}..{GO_SIZES[1]}, "
                                 f"got {self.size!r}")
        elif self.name == "tic_tac_toe":
            if self.size != 3:
                raise ValueError(f"tic-tac-toe is played on a 3x3 board, got board_size={self.size!r}")
        else:
            raise ValueError(f"unknown board game {self.name!r}; known: 'tic_tac_toe', 'go'")

    def load(self) -> pyspiel.Game:
        if self.name == "go":
            return pyspiel.load_game("go", {"board_size": int(self.size), "komi": float(self.komi)})
        return pyspiel.load_game("tic_tac_toe")

    @property
    def num_points(self) -> int:
        return self.size * self.size

    @property
    def pass_action(self) -> int | None:
        """The pass action (Go), or None."""
        return self.num_points if self.name == "go" else None

    @property
    def _planes(self) -> tuple[int, int, int]:
        # (empty, agent, opponent) plane indices in OpenSpiel's observation
        # tensor: tic-tac-toe is [empty, nought (player 1), cross (player 0)],
        # Go is [black (player 0), white (player 1), empty, to-play].
        return (0, 2, 1) if self.name == "tic_tac_toe" else (2, 0, 1)

    def board_planes(self, state: pyspiel.State) -> np.ndarray:
        """(N, N, 3) bool: empty, the agent's pieces, the opponent's pieces."""
        n = self.size
        tensor = np.asarray(state.observation_tensor(AGENT), dtype=np.float32)
        tensor = tensor[: (3 if self.name == "tic_tac_toe" else 4) * n * n].reshape(-1, n, n)
        return np.stack([tensor[p] > 0.5 for p in self._planes], axis=-1)

    def owners(self, state: pyspiel.State) -> np.ndarray:
        """(N*N,) int8: -1 empty, 0 agent, 1 opponent, in action order."""
        planes = self.board_planes(state).reshape(-1, 3)
        owner = np.full(self.num_points, -1, np.int8)
        owner[planes[:, OWN]] = 0
        owner[planes[:, OPPONENT]] = 1
        return owner

    def final_reward(self, state: pyspiel.State) -> float:
        """The agent's reward for a finished game: 1 win, draw_reward, 0 loss."""
        value = state.returns()[AGENT]
        if value > 0:
            return 1.0
        if value < 0:
            return 0.0
        return self.draw_reward
