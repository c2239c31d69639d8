"""MuJoBoard: any registered OpenSpiel board game (`envs.boards.games.GAMES`)
touched with the Jaco arm, beyond the paper's two.

Names registered with `envs.load` and gymnasium (`REGISTERED`), each against
OpenSpiel's MCTS with 100 simulations by default:

* ``mujoboard/connect_four`` (6x7; a touch on any point of a column plays it),
  ``mujoboard/hex-7x7``, ``mujoboard/othello-8x8`` (forced passes are played
  by the referee), ``mujoboard/gomoku-9x9``: placement games;
* ``mujoboard/breakthrough-6x6``, ``mujoboard/checkers`` (8x8),
  ``mujoboard/clobber-5x6``: move games (touch a
  piece, then where it goes; `envs.boards.games`).

The physics, the arm, touch registration (the hardest press wins, every
substep; only finger geoms register, as in MuJoGo) and the arm reset are
MuJoGo's (`envs.boards.task`). ``opponent`` names an OpenSpiel bot
(`abstract_planners.openspiel_bots.make_bot`: ``"mcts:N"``,
``"alphabeta:D"``, ``"random"``), mixed with uniformly random moves at rate
``epsilon``. ``agent_player``: 0 (the agent moves first), 1, or
``"random"`` per episode. Rewards at the game's end: 1 win, 0.5 draw, 0
loss; a game still running at the time limit is truncated (discount 1).
"""

from __future__ import annotations

import math

from abstract_planners.epsilon_greedy import EpsilonGreedy
from abstract_planners.openspiel_bots import make_bot
from envs import _config
from envs.boards import _check_board_common
from envs.boards.games import GAMES, BoardGame
from envs.boards.task import BoardTask, check_agent_player
from envs.boards.task_record import HALF_MOVE_TIMEOUT
from envs.core import Environment
from envs.registry import EnvEntry, register

#: Seconds per agent move in the default time limit (`default_time_limit`).
SECONDS_PER_MOVE = 3.0
#: Bounds (seconds) of the default time limit.
TIME_LIMIT_RANGE = (60.0, 300.0)


def default_time_limit(game: BoardGame) -> float:
    """`SECONDS_PER_MOVE` for each of the agent's moves in the longest game,
    within `TIME_LIMIT_RANGE` (seconds)."""
    longest = game.load().max_game_length()
    low, high = TIME_LIMIT_RANGE
    return float(min(max(SECONDS_PER_MOVE * math.ceil(longest / 2), low), high))


def check_mujoboard(
    *,
    game,
    board_size=None,
    opponent="mcts:100",
    epsilon=0.0,
    agent_player=0,
    seed=None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset=True,
    time_limit=None,
    control_timestep=0.05,
    physics_timestep=0.002,
    registering="fingers",
    half_move_timeout=HALF_MOVE_TIMEOUT,
    piece_noise=None,
    render_size=(256, 256),
    multisamples=0,
    shadows=False,
    raise_on_physics_error=True,
    lazy_cameras=False,
) -> BoardGame:
    """Checks `make_mujoboard`'s arguments without building the physics;
    returns the `BoardGame`."""
    if game not in GAMES:
        raise ValueError(
            f"unknown board game {game!r}; known: " + ", ".join(repr(n) for n in GAMES)
        )
    board = BoardGame(game, board_size if board_size is not None else _first_size(game))
    make_bot(opponent)  # raises for a bad name
    _config.check_real("epsilon", epsilon, low=0.0, high=1.0)
    check_agent_player(agent_player)
    _check_board_common(
        seed=seed,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        arm_reset=arm_reset,
        time_limit=time_limit if time_limit is not None else 60.0,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        piece_noise=piece_noise,
        render_size=render_size,
        multisamples=multisamples,
        shadows=shadows,
        raise_on_physics_error=raise_on_physics_error,
        lazy_cameras=lazy_cameras,
    )
    _config.check_choice("registering", registering, ("arm", "fingers", "fingertips"))
    _config.check_real("half_move_timeout", half_move_timeout, low=0.0, low_open=True, high=3600.0)
    return board


def _first_size(game: str):
    rules = GAMES[game]
    return rules.sizes[0] if rules.sizes else max(rules.min_size, 7)


def make_mujoboard(
    *,
    game: str,
    board_size=None,
    opponent: str = "mcts:100",
    epsilon: float = 0.0,
    agent_player=0,
    seed: int | None = None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset: bool = True,
    time_limit: float | None = None,
    control_timestep: float = 0.05,
    physics_timestep: float = 0.002,
    registering: str = "fingers",
    half_move_timeout: float = HALF_MOVE_TIMEOUT,
    piece_noise=None,
    render_size=(256, 256),
    multisamples: int = 0,
    shadows: bool = False,
    raise_on_physics_error: bool = True,
    lazy_cameras: bool = False,
) -> Environment:
    """A registered OpenSpiel game (``game``, `envs.boards.games.GAMES`) on a
    ``board_size`` board (an int or ``(rows, cols)``; None: the game's
    first size) against the bot ``opponent`` at random-move rate
    ``epsilon``; see the module docstring. ``time_limit`` None:
    `default_time_limit`. Other arguments as `envs.boards.make_mujogo`'s.

    Raises:
      ValueError: an unknown game or bot, or a bad value (named).
    """
    board = check_mujoboard(
        game=game,
        board_size=board_size,
        opponent=opponent,
        epsilon=epsilon,
        agent_player=agent_player,
        seed=seed,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        arm_reset=arm_reset,
        time_limit=time_limit,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        registering=registering,
        half_move_timeout=half_move_timeout,
        piece_noise=piece_noise,
        render_size=render_size,
        multisamples=multisamples,
        shadows=shadows,
        raise_on_physics_error=raise_on_physics_error,
        lazy_cameras=lazy_cameras,
    )
    if time_limit is None:
        time_limit = default_time_limit(board)
    bot = EpsilonGreedy(make_bot(opponent), float(epsilon))
    task = BoardTask(
        board,
        bot,
        registering=registering,
        arm_reset=arm_reset,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        time_limit=time_limit,
        piece_noise=piece_noise,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        render_size=render_size,
        multisamples=multisamples,
        shadows=shadows,
        agent_player=agent_player,
        half_move_timeout=half_move_timeout,
    )
    return Environment(
        task, seed=seed, raise_on_physics_error=raise_on_physics_error, lazy_cameras=lazy_cameras
    )


#: Registered names: (name, game, board size).
REGISTERED = (
    ("connect_four", "connect_four", (6, 7)),
    ("hex-7x7", "hex", 7),
    ("othello-8x8", "othello", 8),
    ("gomoku-9x9", "gomoku", 9),
    ("breakthrough-6x6", "breakthrough", 6),
    ("checkers", "checkers", 8),
    ("clobber-5x6", "clobber", (5, 6)),
)


def register_mujoboard(name: str, game: str, board_size, description: str = "") -> None:
    """Registers ``mujoboard/<name>`` with `envs.load` and gymnasium: ``game``
    on a ``board_size`` board, every `make_mujoboard` argument overridable."""
    rules = GAMES[game]
    BoardGame(game, board_size)  # raises for a size the game does not allow
    register(
        EnvEntry(
            f"mujoboard/{name}",
            make_mujoboard,
            {"game": game, "board_size": board_size},
            description
            or f"MuJoBoard, {rules.description} with a Jaco arm, "
            f"against OpenSpiel MCTS (100 simulations)",
            validate=check_mujoboard,
        )
    )


def _register() -> None:
    for name, game, size in REGISTERED:
        register_mujoboard(name, game, size)


_register()
