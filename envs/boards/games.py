"""The abstract games behind the board environments, on OpenSpiel.

A game is played by touch: OpenSpiel is the referee (legal moves, the
result), and `GameRules` declares how touches on the board's points become
OpenSpiel actions and how the game's state is shown:

* ``input="point"`` (placement games: tic-tac-toe, Go, hex, othello,
  gomoku): a touch on a point plays the action of that point;
* ``input="column"`` (connect four): a touch on any point of a column plays
  that column (pieces fall towards row 0, OpenSpiel's bottom row, the row
  farthest from the arm);
* ``input="move"`` (breakthrough, checkers, clobber): a touch on one of the
  mover's pieces that can move *selects* it; with a piece selected, a touch
  on a point the piece can move to plays that move; a touch on another
  movable piece of the mover selects it instead. Anything else changes
  nothing. The board task clears a selection that is not completed within
  its ``half_move_timeout``. A move's (from, to) points are found from the
  game itself (`BoardGame.move_points`): the point that loses the mover's
  piece and the point that gains it, so no per-game move encoding is
  declared.

`BoardGame` binds rules to a board size and does the arithmetic the task and
the agents share: which points each player holds (`players`, `kings`,
`board_planes`), what a touch on a zone does (`zone_effects`, `touch_effect`)
and which zones an action needs touched, in order (`touches`).

Board coordinates: point ``p`` of a ``rows x cols`` board is ``(p // cols,
p % cols)``, the layout of OpenSpiel's observation tensors; row 0 is the
row farthest from the arm. In Go, row 0 is GTP row 1; in tic-tac-toe, the
row OpenSpiel prints first. Zones are the points, then (Go) the pass area.

New games: `register_game(name, rules)` (see the README's "Add a game").
"""

from __future__ import annotations

import functools
import math
import numbers
from dataclasses import dataclass, field
from typing import Callable, cast

import numpy as np
import pyspiel

from envs._config import check_int

#: board_state planes.
EMPTY, OWN, OPPONENT, KING = 0, 1, 2, 3
#: The agent's OpenSpiel player by default (the paper's: it moves first).
AGENT = 0

GO_SIZES = (5, 19)
INPUTS = ("point", "column", "move")
LAYOUTS = ("square", "hex")
LOOKS = ("checker", "wood", "plain")

#: Piece colours (rgba) of OpenSpiel's player 0 and player 1.
RED_BLUE = ((1.0, 0.0, 0.0, 0.5), (0.0, 0.0, 1.0, 0.5))
BLACK_WHITE = ((0.0, 0.0, 0.0, 0.75), (1.0, 1.0, 1.0, 0.75))
DARK_LIGHT = ((0.15, 0.12, 0.1, 1.0), (0.95, 0.93, 0.88, 1.0))


def _no_params(rows: int, cols: int) -> dict:
    return {}


@dataclass(frozen=True)
class GameRules:
    """How one OpenSpiel two-player, perfect-information game is played by touch.

    Attributes:
      openspiel: OpenSpiel's short name (``"connect_four"``).
      input: ``"point"``, ``"column"`` or ``"move"`` (module docstring).
      owner_planes: the planes of ``state.observation_tensor(0)`` that hold
        player 0's pieces and those that hold player 1's.
      king_planes: planes holding promoted pieces (checkers' kings), shown
        taller; they must also be in ``owner_planes``.
      params: ``(rows, cols) -> dict`` of OpenSpiel parameters for that size.
      sizes: allowed ``(rows, cols)``; empty means square boards of
        `min_size`..`max_size` points a side.
      min_size, max_size: the square sizes allowed when ``sizes`` is empty.
      pass_zones: touch areas beside the board play the pass (Go).
      auto_pass: a pass that is the only legal action is played by the
        referee for either player (othello); the agent never touches it.
      layout: ``"square"`` grid or ``"hex"`` (rows shifted by half a point
        each, a rhombus).
      look: the board's look: ``"checker"`` squares, ``"wood"`` with lines
        through the points (Go), or ``"plain"`` tiles with lines between
        them.
      colours: rgba of player 0's and player 1's pieces.
      draw_reward: the agent's reward for a draw.
      description: a line for registries.
    """

    openspiel: str
    input: str = "point"
    owner_planes: tuple = ((0,), (1,))
    king_planes: tuple = ()
    params: Callable[[int, int], dict] = _no_params
    sizes: tuple = ()
    min_size: int = 3
    max_size: int = 19
    pass_zones: bool = False
    auto_pass: bool = False
    layout: str = "square"
    look: str = "checker"
    colours: tuple = DARK_LIGHT
    draw_reward: float = 0.5
    description: str = ""
    # Derived (`BoardGame.players`): the owner planes' rows, and per row its
    # player + 1 as a (rows, 1) column; player 1's rows last.
    owner_rows: np.ndarray = field(init=False, repr=False, compare=False)
    owner_values: np.ndarray = field(init=False, repr=False, compare=False)

    def __post_init__(self):
        if self.input not in INPUTS:
            raise ValueError(f"input must be one of {INPUTS}, got {self.input!r}")
        if self.layout not in LAYOUTS:
            raise ValueError(f"layout must be one of {LAYOUTS}, got {self.layout!r}")
        if self.look not in LOOKS:
            raise ValueError(f"look must be one of {LOOKS}, got {self.look!r}")
        if len(self.owner_planes) != 2 or not all(self.owner_planes):
            raise ValueError("owner_planes must give the planes of player 0 and of player 1")
        owned = set(self.owner_planes[0]) | set(self.owner_planes[1])
        if not set(self.king_planes) <= owned:
            raise ValueError("king_planes must be among owner_planes")
        if self.pass_zones and self.input != "point":
            raise ValueError("pass_zones need input='point'")
        rows = [(plane, player + 1) for player in (0, 1) for plane in self.owner_planes[player]]
        object.__setattr__(self, "owner_rows", np.array([r for r, _ in rows], np.intp))
        object.__setattr__(self, "owner_values", np.array([[v] for _, v in rows], np.int8))


#: name -> rules; `register_game` adds to it.
GAMES: dict[str, GameRules] = {}


def register_game(name: str, rules: GameRules) -> None:
    """Makes ``name`` a board game the board task can play (`BoardGame`).

    Raises:
      ValueError: ``name`` is taken, or OpenSpiel does not know the game or
        it is not a two-player, sequential, perfect-information game.
    """
    if name in GAMES:
        raise ValueError(f"board game {name!r} is already registered")
    known = {g.short_name for g in pyspiel.registered_games()}
    if rules.openspiel not in known:
        raise ValueError(f"OpenSpiel has no game {rules.openspiel!r}")
    GAMES[name] = rules


@dataclass(frozen=True)
class BoardGame:
    """One registered game at one board size, as the physical task sees it.

    Args:
      name: a registered game (`GAMES`): ``"tic_tac_toe"``, ``"go"``,
        ``"connect_four"``, ...
      size: points per side (an int) or ``(rows, cols)``.
      komi: Go's komi (other games: 0).
      draw_reward: the agent's reward for a drawn game (None: the rules').

    Raises:
      ValueError: an unknown game or a size the game does not allow.
    """

    name: str
    size: int | tuple
    komi: float = 0.0
    draw_reward: float | None = None
    rules: GameRules = field(init=False, repr=False, compare=False)
    rows: int = field(init=False)
    cols: int = field(init=False)

    def __post_init__(self):
        rules = GAMES.get(self.name)
        if rules is None:
            raise ValueError(
                f"unknown board game {self.name!r}; known: " + ", ".join(repr(n) for n in GAMES)
            )
        size = self.size
        if isinstance(size, (tuple, list)) and len(size) == 2:
            rows, cols = size
        else:
            rows = cols = size
        if rules.sizes:
            ok = (
                all(
                    isinstance(v, numbers.Integral) and not isinstance(v, bool)
                    for v in (rows, cols)
                )
                and (int(rows), int(cols)) in rules.sizes
            )
            if not ok:
                shown = ", ".join(f"{r}x{c}" for r, c in rules.sizes)
                raise ValueError(
                    f"{self.name} is played on {shown} boards, got board_size={self.size!r}"
                )
        else:
            if rows != cols:
                raise ValueError(f"{self.name} is played on square boards, got {self.size!r}")
            check_int("board_size", rows, rules.min_size, rules.max_size)
        object.__setattr__(self, "rules", rules)
        object.__setattr__(self, "rows", int(rows))
        object.__setattr__(self, "cols", int(cols))
        object.__setattr__(self, "size", int(rows) if rows == cols else (int(rows), int(cols)))
        if self.draw_reward is None:
            object.__setattr__(self, "draw_reward", float(rules.draw_reward))

    @staticmethod
    def from_description(description) -> "BoardGame":
        """The game a task's public description (`envs.description.BoardDescription`)
        names, built once per (game, size, komi) in a process."""
        return _from_description(description.game, description.board_size, float(description.komi))

    # -- the OpenSpiel game ---------------------------------------------------

    def load(self) -> pyspiel.Game:
        """The OpenSpiel game (loaded once per `BoardGame`; pyspiel caches it too)."""
        params = dict(self.rules.params(self.rows, self.cols))
        if self.name == "go":
            params["komi"] = float(self.komi)
        return pyspiel.load_game(self.rules.openspiel, params)

    @property
    def num_points(self) -> int:
        return self.rows * self.cols

    @property
    def pass_action(self) -> int | None:
        """The pass action played by touching a pass area (Go), or None."""
        return self.num_points if self.rules.pass_zones else None

    @property
    def num_zones(self) -> int:
        """Touch zones: the points, then the pass area if any."""
        return self.num_points + (1 if self.rules.pass_zones else 0)

    @property
    def has_kings(self) -> bool:
        return bool(self.rules.king_planes)

    # -- the state as pieces ------------------------------------------------

    def _tensor(self, state) -> np.ndarray:
        tensor = np.asarray(state.observation_tensor(0), dtype=np.float32)
        return tensor.reshape(-1, self.num_points)

    def players(self, state) -> np.ndarray:
        """(num_points,) int8: -1 empty, else the OpenSpiel player (0, 1) whose piece it is."""
        rules = self.rules  # a point's owner: the largest player + 1 of its planes, less 1
        owned = self._tensor(state)[rules.owner_rows] > 0.5
        return (owned * rules.owner_values).max(axis=0) - np.int8(1)

    def kings(self, state) -> np.ndarray:
        """(num_points,) bool: the point holds a promoted piece."""
        if not self.rules.king_planes:
            return np.zeros(self.num_points, bool)
        # numpy's stubs type ``any(axis=0)`` as a bool or an array; it is an array here.
        return cast(
            np.ndarray, (self._tensor(state)[list(self.rules.king_planes)] > 0.5).any(axis=0)
        )

    def owners(self, state, agent: int = AGENT) -> np.ndarray:
        """(num_points,) int8: -1 empty, 0 the agent's piece, 1 the opponent's."""
        players = self.players(state)
        return np.where(players < 0, -1, (players != agent).astype(np.int8)).astype(np.int8)

    @property
    def num_planes(self) -> int:
        return 4 if self.has_kings else 3

    def board_planes(self, state, agent: int = AGENT) -> np.ndarray:
        """(rows, cols, 3) bool: empty, the agent's pieces, the opponent's
        pieces; games with kings add a fourth plane, the promoted pieces."""
        owners = self.owners(state, agent)
        planes = [owners < 0, owners == 0, owners == 1]
        if self.has_kings:
            planes.append(self.kings(state))
        return np.stack(planes, axis=-1).reshape(self.rows, self.cols, -1)

    def final_reward(self, state, agent: int = AGENT) -> float:
        """The agent's reward for a finished game: 1 win, draw_reward, 0 loss."""
        value = state.returns()[agent]
        if value > 0:
            return 1.0
        if value < 0:
            return 0.0
        assert self.draw_reward is not None  # `__post_init__` sets the rules' by default
        return self.draw_reward

    # -- touches ------------------------------------------------------------

    def forced_pass(self, state) -> int | None:
        """The pass the referee plays for the mover (``auto_pass`` games, when
        it is the only legal action), or None."""
        if not self.rules.auto_pass or state.is_terminal():
            return None
        legal = state.legal_actions()
        if len(legal) == 1 and legal[0] >= self.num_points:
            return int(legal[0])
        return None

    def move_points(self, state) -> dict[int, tuple[int, int]]:
        """Move games: every legal action -> (from point, to point), found by
        playing it: the point that loses the mover's piece and the point
        that gains one.

        Raises:
          ValueError: an action does not move exactly one of the mover's
            pieces, or two actions share (from, to) (the rules then need
            more than two touches).
        """
        mover = state.current_player()
        before = self.players(state) == mover
        out: dict[int, tuple[int, int]] = {}
        seen: dict[tuple[int, int], int] = {}  # (from, to) -> the action moving so
        for action in state.legal_actions():
            after = self.players(state.child(action)) == mover
            lost = np.flatnonzero(before & ~after)
            gained = np.flatnonzero(after & ~before)
            if len(lost) != 1 or len(gained) != 1:
                raise ValueError(
                    f"{self.name}: action {state.action_to_string(mover, action)} "
                    f"does not move one piece ({len(lost)} lost, "
                    f"{len(gained)} gained)"
                )
            pair = (int(lost[0]), int(gained[0]))
            if pair in seen:
                raise ValueError(
                    f"{self.name}: actions {seen[pair]} and {action} both move "
                    f"{pair[0]} -> {pair[1]}"
                )
            seen[pair] = action
            out[int(action)] = pair
        return out

    def zone_effects(self, state, selected: int = -1) -> tuple[np.ndarray, np.ndarray]:
        """What a touch on each zone does now: ``(act, select)``, ``act``
        (num_zones,) int: the action it plays or -1; ``select`` (num_zones,)
        bool: it selects that point's piece (move games). ``selected`` is the
        point selected by the half move in progress, or -1. Nothing happens
        in a finished game."""
        act = np.full(self.num_zones, -1, np.int64)
        select = np.zeros(self.num_zones, bool)
        if state.is_terminal():
            return act, select
        legal = np.asarray(state.legal_actions(), np.int64)
        kind = self.rules.input
        if kind == "point":
            on_board = legal[legal < self.num_zones]
            act[on_board] = on_board
        elif kind == "column":
            cols = legal[legal < self.cols]
            points = (np.arange(self.rows)[:, None] * self.cols + cols[None, :]).ravel()
            act[points] = np.tile(cols, self.rows)
        else:
            moves = self.move_points(state)
            for action, (src, dst) in moves.items():
                select[src] = True
                if src == selected:
                    act[dst] = action
            if 0 <= selected < self.num_points:
                select[selected] = False  # pressing it again changes nothing
        return act, select

    def touch_effect(self, state, zone: int, selected: int = -1) -> tuple[str, int] | None:
        """What touching ``zone`` does: ``("move", action)``, ``("select",
        point)`` or None (nothing)."""
        act, select = self.zone_effects(state, selected)
        if not 0 <= zone < self.num_zones:
            return None
        if act[zone] >= 0:
            return "move", int(act[zone])
        if select[zone]:
            return "select", int(zone)
        return None

    def touches(self, state, action: int) -> tuple[int, ...]:
        """The zones to touch, in order, to play ``action`` from ``state``:
        its point; a column's point in the middle row (the easiest to
        reach); a move's (from, to); the pass zone (Go).

        Raises:
          ValueError: ``action`` is not legal in ``state``.
        """
        action = int(action)
        if state.is_terminal() or action not in state.legal_actions():
            raise ValueError(f"action {action} is not legal here")
        kind = self.rules.input
        if kind == "point":
            if action >= self.num_zones:
                raise ValueError(f"action {action} is played by the referee, not by a touch")
            return (action,)
        if kind == "column":
            return ((self.rows // 2) * self.cols + action,)
        return self.move_points(state)[action]


@functools.lru_cache(maxsize=32)
def _from_description(name: str, board_size, komi: float) -> BoardGame:
    return BoardGame(name, board_size, komi=komi)


# -- the games ------------------------------------------------------------------

register_game(
    "tic_tac_toe",
    GameRules(
        "tic_tac_toe",
        owner_planes=((2,), (1,)),
        sizes=((3, 3),),
        colours=RED_BLUE,
        description="tic-tac-toe",
    ),
)
register_game(
    "go",
    GameRules(
        "go",
        owner_planes=((0,), (1,)),
        min_size=GO_SIZES[0],
        max_size=GO_SIZES[1],
        params=lambda r, c: {"board_size": r},
        pass_zones=True,
        look="wood",
        colours=BLACK_WHITE,
        draw_reward=0.0,
        description="Go, Tromp-Taylor",
    ),
)
register_game(
    "connect_four",
    GameRules(
        "connect_four",
        input="column",
        sizes=((6, 7),),
        params=lambda r, c: {"rows": r, "columns": c},
        look="plain",
        colours=RED_BLUE,
        description="connect four: a touch anywhere on a column drops a piece in it",
    ),
)
register_game(
    "hex",
    GameRules(
        "hex",
        min_size=5,
        max_size=11,
        layout="hex",
        look="plain",
        colours=RED_BLUE,
        params=lambda r, c: {
            "board_size": r,
            "num_rows": r,
            "num_cols": c,
            "plain_obs_tensor": True,
        },
        description="hex: red joins the far and near edges, blue the left and right",
    ),
)
register_game(
    "othello",
    GameRules(
        "othello",
        owner_planes=((1,), (2,)),
        sizes=((8, 8),),
        auto_pass=True,
        look="plain",
        colours=BLACK_WHITE,
        description="othello: flips shown, a forced pass is played by the referee",
    ),
)
register_game(
    "gomoku",
    GameRules(
        "gomoku",
        min_size=7,
        max_size=15,
        params=lambda r, c: {"size": r, "connect": 5},
        look="wood",
        colours=BLACK_WHITE,
        description="gomoku: five in a row",
    ),
)
register_game(
    "breakthrough",
    GameRules(
        "breakthrough",
        input="move",
        min_size=5,
        max_size=8,
        params=lambda r, c: {"rows": r, "columns": c},
        colours=RED_BLUE,
        description="breakthrough: touch a piece, then where it goes",
    ),
)
register_game(
    "checkers",
    GameRules(
        "checkers",
        input="move",
        owner_planes=((0, 1), (2, 3)),
        king_planes=(1, 3),
        sizes=((8, 8),),
        params=lambda r, c: {"rows": r, "columns": c},
        colours=RED_BLUE,
        description="checkers: touch a piece, then where it goes; each jump is a move",
    ),
)
register_game(
    "clobber",
    GameRules(
        "clobber",
        input="move",
        sizes=((5, 6), (6, 6), (7, 7), (8, 8)),
        params=lambda r, c: {"rows": r, "columns": c},
        look="plain",
        colours=RED_BLUE,
        description="clobber: touch a piece, then the adjacent piece it takes",
    ),
)


def hex_offset(rows: int) -> float:
    """Hex layout: how far (in points) the last row is shifted from the first."""
    return 0.5 * (rows - 1)


def layout_width(game: BoardGame) -> float:
    """The board's width in point spacings (the hex rhombus is wider)."""
    return game.cols + (hex_offset(game.rows) if game.rules.layout == "hex" else 0.0)


def layout_depth(game: BoardGame) -> float:
    """The board's depth in point spacings."""
    return game.rows * (math.sqrt(3) / 2 if game.rules.layout == "hex" else 1.0)
