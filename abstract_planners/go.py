"""Go planners on OpenSpiel ``go`` states: GNU Go over GTP, and OpenSpiel's MCTS.

OpenSpiel's go (``pyspiel.load_game("go", {"board_size": N, "komi": K})``):

* player 0 is Black and moves first; the players alternate strictly, a pass
  is an ordinary action in ``state.history()`` (action ``N * N``); two passes
  in a row end the game, as does reaching ``max_game_length = 2 * N * N``
  moves;
* a point's action id is ``row * N + column`` with row 0 the **bottom** row
  (GTP row 1) and column 0 the left column (``A``): action 0 is ``A1``,
  action ``N`` is ``A2``, action ``N * N - 1`` the top-right corner. Column
  letters skip ``I`` exactly as GTP does (OpenSpiel's own board printout and
  ``action_to_string`` use the same letters, in lower case);
* simple ko and no suicide, like GNU Go's defaults; the final score
  (``state.returns()``, +1/-1) is Tromp-Taylor area scoring with **no
  dead-stone removal**: a dead stone left on the board counts as alive.

`GnuGoPlanner` therefore asks GNU Go with ``kgs-genmove_cleanup`` by default,
which does not pass while dead opponent stones remain on the board.
"""

from __future__ import annotations

import numbers
import shutil
import time
import warnings

import pyspiel

from abstract_planners.base import Planner, Subgoal
from abstract_planners.board_random import check_decision_state
from abstract_planners.gtp import INSTALL_HINT, GnuGoNotFoundError, GTPClient, default_gnugo_command
from abstract_planners.gtp_process import close_quietly
from abstract_planners.openspiel_bots import MCTSPlanner, _check_int, _check_real

__all__ = [
    "GTP_COLUMNS",
    "MIN_BOARD_SIZE",
    "MAX_BOARD_SIZE",
    "go_game",
    "pass_action",
    "action_to_vertex",
    "vertex_to_action",
    "GnuGoPlanner",
    "MCTSPlanner",
]

#: GTP column letters: ``A``..``Z`` without ``I``.
GTP_COLUMNS = "ABCDEFGHJKLMNOPQRSTUVWXYZ"
MIN_BOARD_SIZE, MAX_BOARD_SIZE = 5, 19


def go_game(board_size: int = 7, komi: float = 5.5) -> pyspiel.Game:
    """The OpenSpiel go game with that board size (5..19) and komi.

    Raises:
      ValueError: ``board_size`` outside 5..19 or not an integer; ``komi`` not
        a finite number.
    """
    board_size = _check_int(board_size, "board_size", MIN_BOARD_SIZE, MAX_BOARD_SIZE)
    komi = _check_real(komi, "komi")
    return pyspiel.load_game("go", {"board_size": board_size, "komi": komi})


def pass_action(board_size: int) -> int:
    """OpenSpiel go's pass action: ``board_size * board_size``."""
    return board_size * board_size


def _check_size(board_size) -> int:
    return _check_int(board_size, "board_size", 1, len(GTP_COLUMNS))


def action_to_vertex(action: int, board_size: int) -> str:
    """OpenSpiel go action id -> GTP vertex (``"A1"`` = action 0, ``"pass"``).

    Raises:
      ValueError: ``action`` outside 0..board_size**2.
    """
    n = _check_size(board_size)
    if (
        isinstance(action, bool)
        or not isinstance(action, numbers.Integral)
        or not 0 <= action <= n * n
    ):
        raise ValueError(
            f"action must be an integer in the range 0..{n * n} for board_size {n}, got {action!r}"
        )
    action = int(action)
    if action == n * n:
        return "pass"
    row, column = divmod(action, n)
    return f"{GTP_COLUMNS[column]}{row + 1}"


def vertex_to_action(vertex: str, board_size: int) -> int:
    """GTP vertex (``"D4"``, ``"d4"``, ``"pass"``) -> OpenSpiel go action id.

    Raises:
      ValueError: not a vertex of that board (``"resign"``, ``"I3"``, off-board).
    """
    n = _check_size(board_size)
    text = str(vertex).strip().upper()
    if text == "PASS":
        return n * n
    column = GTP_COLUMNS.find(text[:1]) if text else -1
    digits = text[1:]
    if column < 0 or column >= n or not digits.isdigit() or not 1 <= int(digits) <= n:
        raise ValueError(
            f"{vertex!r} is not a GTP vertex of a {n}x{n} board "
            f"(columns {GTP_COLUMNS[0]}..{GTP_COLUMNS[n - 1]} without I, rows 1..{n}, "
            f"or 'pass')"
        )
    return (int(digits) - 1) * n + column


def _go_params(state, who: str) -> dict:
    check_decision_state(state, who)
    game = state.get_game()
    if game.get_type().short_name != "go":
        raise ValueError(
            f"{who} plans OpenSpiel go states, got a {game.get_type().short_name!r} state"
        )
    return game.get_parameters()


class GnuGoPlanner(Planner):
    """GNU Go (over GTP) as a planner on OpenSpiel go states.

    Args:
      level: GNU Go's strength, 1..10.
      board_size, komi: the game GNU Go is set up for; `plan` raises
        ValueError for a state of another board size or komi.
      timeout: seconds per GTP command (see `GTPClient`).
      command: the engine command line (default ``gnugo --mode gtp
        --chinese-rules --capture-all-dead``, `gtp.GNUGO_FLAGS`).
      seed: GNU Go's random seed (``set_random_seed``); None keeps GNU Go's
        default. ``reset(seed)`` sets it too.
      cleanup: ask with ``kgs-genmove_cleanup`` (default True): GNU Go then
        does not pass while dead opponent stones remain, which matters because
        OpenSpiel scores the board as it stands (Tromp-Taylor). False uses
        plain ``genmove``.

    The engine starts on the first `plan` after construction or `reset` (a
    missing ``gnugo`` is reported by the constructor: `GnuGoNotFoundError`).
    Each `plan(state)` syncs the engine to ``state.history()``: when the
    moves already on the engine are a prefix of it only the new ones are
    played, otherwise the board is cleared and the whole history replayed
    (Black first, colours alternating, passes included). Then GNU Go generates
    the move of the player to move.

    Choices:

    * **resign**: GNU Go resigning means it considers the game lost.
      OpenSpiel's go has no resign action, so the planner returns the pass
      action with ``info["resigned"] = True``; callers must honour the flag:
      the board environments (`envs.boards.task.BoardTask`) end the game
      there as the agent's win and play nothing.
    * **a move OpenSpiel calls illegal** (should not happen: both use simple
      ko and forbid suicide): a `RuntimeWarning` and the pass action (always
      legal) with ``info["illegal_engine_move"]`` set to GNU Go's vertex; the
      engine is resynchronised on the next call.

    Subgoal info: ``vertex`` (GNU Go's answer), ``ms`` (genmove wall time),
    ``resigned``, and ``illegal_engine_move`` when it happened.
    """

    name = "gnugo"

    def __init__(
        self,
        level: int = 10,
        *,
        board_size: int = 7,
        komi: float = 5.5,
        timeout: float = 10.0,
        command=None,
        seed: int | None = None,
        cleanup: bool = True,
    ):
        self.level = _check_int(level, "level", 1, 10)
        self.board_size = _check_int(board_size, "board_size", MIN_BOARD_SIZE, MAX_BOARD_SIZE)
        self.komi = _check_real(komi, "komi")
        timeout = _check_real(timeout, "timeout")
        if timeout <= 0:
            raise ValueError(f"timeout must be > 0 seconds, got {timeout!r}")
        self.timeout = timeout
        if command is None:
            command = default_gnugo_command()
        elif isinstance(command, str):
            command = command.split()
        self.command = [str(part) for part in command]
        if not self.command or shutil.which(self.command[0]) is None:
            raise GnuGoNotFoundError(
                f"GTP engine executable {self.command[:1]} not found; for GNU Go, {INSTALL_HINT}"
            )
        self.cleanup = bool(cleanup)
        self._seed = None if seed is None else int(seed)
        self._client: GTPClient | None = None
        self._moves: list[int] | None = None  # actions on the engine's board since clear
        #: Wall time in ms of every genmove so far (for benchmarks).
        self.genmove_ms: list[float] = []

    @property
    def client(self) -> GTPClient:
        """The GTP client, started and set up on first use."""
        if self._client is None:
            client = GTPClient(self.command, timeout=self.timeout, name="gnugo")
            try:
                client.boardsize(self.board_size)
                client.komi(self.komi)
                client.set_level(self.level)
                if self._seed is not None:
                    client.set_random_seed(self._seed)
            except BaseException:
                client.close()
                raise
            self._client = client
            self._moves = []
        return self._client

    def reset(self, seed: int | None = None) -> None:
        """A new game: the engine is stopped, and the next `plan` starts a
        fresh one (with ``seed`` when given). GNU Go keeps what it read in
        earlier games across ``clear_board``, so a kept engine's moves, and
        with them a seeded episode's, depended on the games played before
        it in the process (about 20 ms a game)."""
        if seed is not None:
            self._seed = int(seed) % (2**31)
        self.close()

    def _sync(self, history: list[int]) -> None:
        client = self.client
        moves = self._moves
        if moves is None or moves != history[: len(moves)]:
            client.clear_board()
            self._moves = moves = []
        for index in range(len(moves), len(history)):
            action = history[index]
            client.play("b" if index % 2 == 0 else "w", action_to_vertex(action, self.board_size))
            moves.append(action)

    def plan(self, state) -> Subgoal:
        params = _go_params(state, self.name)
        if params["board_size"] != self.board_size or params["komi"] != self.komi:
            raise ValueError(
                f"{self.name} is set up for board_size={self.board_size}, komi={self.komi:g}; "
                f"got a state with board_size={params['board_size']}, komi={params['komi']:g}"
            )
        if params.get("handicap", 0):
            raise ValueError(
                f"{self.name} does not support handicap games (handicap={params['handicap']})"
            )
        history = [int(a) for a in state.history()]
        color = "b" if len(history) % 2 == 0 else "w"
        self._sync(history)
        start = time.perf_counter()
        vertex = self.client.genmove(color, cleanup=self.cleanup)
        ms = (time.perf_counter() - start) * 1e3
        self.genmove_ms.append(ms)
        info = {"vertex": vertex, "ms": ms, "resigned": vertex == "resign"}
        passed = pass_action(self.board_size)
        if vertex == "resign":
            action = passed
        else:
            action = vertex_to_action(vertex, self.board_size)
            assert self._moves is not None  # `_sync` above set it
            self._moves.append(action)
            if action not in state.legal_actions():
                warnings.warn(
                    f"GNU Go played {vertex} (action {action}), which OpenSpiel calls illegal "
                    f"for {color} at\n{state}\nplaying pass instead",
                    RuntimeWarning,
                    stacklevel=2,
                )
                info["illegal_engine_move"] = vertex
                self._moves = None  # resynchronise from scratch next time
                action = passed
        return Subgoal(action, state.child(action), info=info)

    def close(self) -> None:
        if self._client is not None:
            self._client.close()
            self._client = None
            self._moves = None

    def __del__(self):
        close_quietly(self)

    def __repr__(self) -> str:
        return f"GnuGoPlanner(level={self.level}, board_size={self.board_size}, komi={self.komi:g})"
