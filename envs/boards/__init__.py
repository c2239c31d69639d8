"""MuJoXO and MuJoGo: tic-tac-toe and Go touched with a Jaco arm (Mirza et al.
2020); MuJoBoard: other OpenSpiel games (`envs.boards.mujoboard`).

Names registered with `envs.load` and gymnasium:

* ``mujoxo/mixture`` (opponent: minimax with random moves at epsilon 0.25,
  the paper's), ``mujoxo/optimal`` (epsilon 0), ``mujoxo/random`` (epsilon 1);
* ``mujogo/7x7`` (GNU Go level 10, epsilon 0, the paper's),
  ``mujogo/7x7-mixture`` (epsilon 0.2), ``mujogo/7x7-eval`` (60 s limit),
  ``mujogo/9x9``.

See `envs.boards.task` for the physical rules. The defaults are the original
task's (DeepMind's ``physics_planning_games``; where its code and the paper
disagree, the paper's: komi 5.5, GNU Go level 10 without random moves, one
84x84 front camera). Options that deviate from it: ``physics_timestep``
(original 0.002 s; our earlier versions used 0.005), ``piece_noise``,
``arm_reset=False``, MuJoGo's ``registering`` (``"fingertips"``: only the
tips; ``"arm"``: any contact) and ``allow_double_pass``, and 9x9 Go (the
original only has 7x7; larger boards shrink the squares to keep its width).
"""

from __future__ import annotations

import numbers
import shutil

from abstract_planners.epsilon_greedy import EpsilonGreedy
from abstract_planners.go import GnuGoPlanner
from abstract_planners.tictactoe import MinimaxPlanner
from envs.boards.games import BoardGame
from envs.boards.task import BoardTask, check_agent_player
from envs import _config
from envs.core import Environment
from envs.registry import EnvEntry, register


def _check_epsilon(epsilon) -> float:
    if (
        not isinstance(epsilon, numbers.Real)
        or isinstance(epsilon, bool)
        or not 0.0 <= float(epsilon) <= 1.0
    ):
        raise ValueError(f"epsilon must be a number in [0, 1], got {epsilon!r}")
    return float(epsilon)


def _check_level(level) -> int:
    if (
        not isinstance(level, numbers.Integral)
        or isinstance(level, bool)
        or not 1 <= int(level) <= 10
    ):
        raise ValueError(f"level (GNU Go strength) must be an integer in 1..10, got {level!r}")
    return int(level)


def _check_board_common(
    *,
    seed,
    front_camera,
    front_camera_2,
    arm_reset,
    time_limit,
    control_timestep,
    physics_timestep,
    piece_noise,
    render_size,
    multisamples,
    shadows,
    raise_on_physics_error,
    lazy_cameras,
) -> None:
    _config.check_common(seed, render_size, raise_on_physics_error, lazy_cameras)
    _config.check_int("multisamples", multisamples, 0, 16)
    _config.check_bool("shadows", shadows)
    _config.check_camera("front_camera", front_camera)
    _config.check_camera("front_camera_2", front_camera_2)
    _config.check_bool("arm_reset", arm_reset)
    _config.check_timing(time_limit, control_timestep, physics_timestep)
    if piece_noise is not None:
        _config.check_real("piece_noise", piece_noise, low=0.0, high=1.0)


def check_mujoxo(
    *,
    epsilon: float = 0.25,
    agent_player=0,
    seed=None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset=True,
    time_limit=30.0,
    control_timestep=0.05,
    physics_timestep=0.002,
    piece_noise=None,
    render_size=(256, 256),
    multisamples=0,
    shadows=False,
    raise_on_physics_error=True,
    lazy_cameras=False,
) -> None:
    """Checks `make_mujoxo`'s arguments without building anything (`envs._config`)."""
    _check_epsilon(epsilon)
    check_agent_player(agent_player)
    _check_board_common(
        seed=seed,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        arm_reset=arm_reset,
        time_limit=time_limit,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        piece_noise=piece_noise,
        render_size=render_size,
        multisamples=multisamples,
        shadows=shadows,
        raise_on_physics_error=raise_on_physics_error,
        lazy_cameras=lazy_cameras,
    )


def check_mujogo(
    *,
    board_size=7,
    level=10,
    epsilon=0.0,
    komi=5.5,
    agent_player=0,
    seed=None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset=True,
    time_limit=45.0,
    control_timestep=0.05,
    physics_timestep=0.002,
    registering="fingers",
    allow_double_pass=False,
    piece_noise=None,
    gnugo_timeout=10.0,
    gnugo_command=None,
    render_size=(256, 256),
    multisamples=0,
    shadows=False,
    raise_on_physics_error=True,
    lazy_cameras=False,
) -> None:
    """Checks `make_mujogo`'s arguments without building anything or starting
    GNU Go (`envs._config`)."""
    _config.check_int("board_size", board_size, 5, 19)
    _check_level(level)
    _check_epsilon(epsilon)
    check_agent_player(agent_player)
    _config.check_real("komi", komi, low=-1000.0, high=1000.0)
    _check_board_common(
        seed=seed,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        arm_reset=arm_reset,
        time_limit=time_limit,
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
    _config.check_bool("allow_double_pass", allow_double_pass)
    _config.check_real("gnugo_timeout", gnugo_timeout, low=0.0, low_open=True, high=86_400.0)
    if gnugo_command is not None:
        words = gnugo_command.split() if isinstance(gnugo_command, str) else gnugo_command
        if (
            isinstance(words, (bytes, numbers.Number))
            or not hasattr(words, "__iter__")
            or isinstance(words, dict)
        ):
            raise TypeError(
                f"gnugo_command must be a command line (a str or a list of str), "
                f"got {_config._show(gnugo_command)}"
            )
        words = list(words)
        if not words or not all(isinstance(w, str) and w and "\0" not in w for w in words):
            raise ValueError(
                f"gnugo_command must be a non-empty list of non-empty str, "
                f"got {_config._show(gnugo_command)}"
            )
        if shutil.which(words[0]) is None:
            raise ValueError(f"gnugo_command: executable {words[0]!r} not found")


def make_mujoxo(
    *,
    epsilon: float = 0.25,
    agent_player=0,
    seed: int | None = None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset: bool = True,
    time_limit: float = 30.0,
    control_timestep: float = 0.05,
    physics_timestep: float = 0.002,
    piece_noise: float | None = None,
    render_size=(256, 256),
    multisamples: int = 0,
    shadows: bool = False,
    raise_on_physics_error: bool = True,
    lazy_cameras: bool = False,
) -> Environment:
    """MuJoXO: tic-tac-toe against minimax mixed with random moves at rate ``epsilon``.

    Any contact pressing a square's touch sensor registers a move. Rewards at
    the game's end: 1 win, 0.5 draw, 0 loss. Time limit 30 s (600 control
    steps), then truncation. ``agent_player``: the agent's OpenSpiel player,
    0 (crosses, moves first: the paper's), 1 (noughts; the opponent's first
    move is on the board in the first observation) or ``"random"`` (drawn
    per episode; the ``agent_player`` observation says which).
    ``piece_noise``: the opponent's pieces land within this fraction of the
    sensor half-size (None: the original's 1).
    ``front_camera_2``: ``(height, width)`` of the original code's second
    view (a higher, steeper front camera), off by default as in the paper.
    Looks: ``multisamples`` (samples per pixel, default 0) and ``shadows``
    (the light casts shadows, default False); the original code draws its
    frames with 4 samples and shadows (``multisamples=4, shadows=True``),
    at many times the cost per frame (README, "Looks of the board games").
    """
    check_mujoxo(
        epsilon=epsilon,
        agent_player=agent_player,
        seed=seed,
        front_camera=front_camera,
        front_camera_2=front_camera_2,
        arm_reset=arm_reset,
        time_limit=time_limit,
        control_timestep=control_timestep,
        physics_timestep=physics_timestep,
        piece_noise=piece_noise,
        render_size=render_size,
        multisamples=multisamples,
        shadows=shadows,
        raise_on_physics_error=raise_on_physics_error,
        lazy_cameras=lazy_cameras,
    )
    epsilon = _check_epsilon(epsilon)
    opponent = EpsilonGreedy(MinimaxPlanner(), epsilon)
    task = BoardTask(
        BoardGame("tic_tac_toe", 3, draw_reward=0.5),
        opponent,
        registering="arm",
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
    )
    return Environment(
        task, seed=seed, raise_on_physics_error=raise_on_physics_error, lazy_cameras=lazy_cameras
    )


def make_mujogo(
    *,
    board_size: int = 7,
    level: int = 10,
    epsilon: float = 0.0,
    komi: float = 5.5,
    agent_player=0,
    seed: int | None = None,
    front_camera=(84, 84),
    front_camera_2=None,
    arm_reset: bool = True,
    time_limit: float = 45.0,
    control_timestep: float = 0.05,
    physics_timestep: float = 0.002,
    registering: str = "fingers",
    allow_double_pass: bool = False,
    piece_noise: float | None = None,
    gnugo_timeout: float = 10.0,
    gnugo_command=None,
    render_size=(256, 256),
    multisamples: int = 0,
    shadows: bool = False,
    raise_on_physics_error: bool = True,
    lazy_cameras: bool = False,
) -> Environment:
    """MuJoGo: Go (Tromp-Taylor, komi 5.5) against GNU Go at ``level``, random at ``epsilon``.

    A press registers only if a finger geom (knuckle or tip; ``registering=
    "fingertips"``: tips only) touches the pressed square; the pass areas are
    left and right of the board (at floor level); a second consecutive pass
    by the agent is ignored unless ``allow_double_pass``. ``piece_noise``:
    the opponent's stones land within this fraction of the sensor half-size
    (None: the original's 0.25). Reward 1 for a win, 0 for a loss; a game still running at the
    time limit (45 s; 60 s for evaluation) is a loss. ``gnugo_command`` runs
    another GTP engine (a list of arguments); ``gnugo_timeout`` bounds every
    GTP reply (seconds): a hung engine raises ``GTPError``, a dead one is
    restarted and replays the game. ``agent_player`` (0: black, the
    paper's; 1: white; ``"random"``), ``front_camera_2``, ``multisamples``,
    ``shadows``: as in `make_mujoxo`.
    """
    options = dict(locals())  # the keyword arguments above: no other name is bound yet
    check_mujogo(**options)
    return _build_mujogo(**options)


def _build_mujogo(
    *,
    board_size,
    level,
    epsilon,
    komi,
    agent_player,
    seed,
    front_camera,
    front_camera_2,
    arm_reset,
    time_limit,
    control_timestep,
    physics_timestep,
    registering,
    allow_double_pass,
    piece_noise,
    gnugo_timeout,
    gnugo_command,
    render_size,
    multisamples,
    shadows,
    raise_on_physics_error,
    lazy_cameras,
) -> Environment:
    """Builds `make_mujogo`'s environment from its checked arguments (`check_mujogo`);
    GNU Go is closed again if building the task or environment fails."""
    game = BoardGame("go", board_size, komi=float(komi), draw_reward=0.0)
    epsilon = _check_epsilon(epsilon)
    level = _check_level(level)
    opponent = EpsilonGreedy(
        GnuGoPlanner(
            level,
            board_size=int(board_size),
            komi=float(komi),
            timeout=gnugo_timeout,
            command=gnugo_command,
        ),
        epsilon,
    )
    try:
        task = BoardTask(
            game,
            opponent,
            registering=registering,
            arm_reset=arm_reset,
            front_camera=front_camera,
            front_camera_2=front_camera_2,
            time_limit=time_limit,
            timeout_is_loss=True,
            allow_double_pass=allow_double_pass,
            piece_noise=piece_noise,
            control_timestep=control_timestep,
            physics_timestep=physics_timestep,
            render_size=render_size,
            multisamples=multisamples,
            shadows=shadows,
            agent_player=agent_player,
        )
        return Environment(
            task,
            seed=seed,
            raise_on_physics_error=raise_on_physics_error,
            lazy_cameras=lazy_cameras,
        )
    except BaseException:
        opponent.close()
        raise


def _register() -> None:
    for name, eps, text in (
        ("mixture", 0.25, "random moves at rate 0.25 (the paper's)"),
        ("optimal", 0.0, "always optimal"),
        ("random", 1.0, "always random"),
    ):
        register(
            EnvEntry(
                f"mujoxo/{name}",
                make_mujoxo,
                {"epsilon": eps},
                f"MuJoXO, tic-tac-toe with a Jaco arm; minimax opponent {text}",
                validate=check_mujoxo,
            )
        )
    register(
        EnvEntry(
            "mujogo/7x7",
            make_mujogo,
            {"board_size": 7},
            "MuJoGo, 7x7 Go with a Jaco arm against GNU Go level 10 (the paper's)",
            validate=check_mujogo,
        )
    )
    register(
        EnvEntry(
            "mujogo/7x7-mixture",
            make_mujogo,
            {"board_size": 7, "epsilon": 0.2},
            "MuJoGo 7x7, GNU Go level 10 with random moves at rate 0.2",
            validate=check_mujogo,
        )
    )
    register(
        EnvEntry(
            "mujogo/7x7-eval",
            make_mujogo,
            {"board_size": 7, "time_limit": 60.0},
            "MuJoGo 7x7 with the paper's 60 s evaluation time limit",
            validate=check_mujogo,
        )
    )
    register(
        EnvEntry(
            "mujogo/9x9",
            make_mujogo,
            {"board_size": 9},
            "MuJoGo, 9x9 Go against GNU Go level 10",
            validate=check_mujogo,
        )
    )


_register()

from envs.boards.mujoboard import make_mujoboard  # noqa: E402  (registers mujoboard/*)

__all__ = ["BoardGame", "BoardTask", "make_mujoboard", "make_mujogo", "make_mujoxo"]
