"""Which planners, skills and estimators fit which environment, by name.

    agent = make_agent("mujoban/level5-pegs", env)                      # defaults
    agent = make_agent("mujoban/level5-pegs", env, planner="random")    # swap one part

Families: ``mujoban`` (Sokoban states, the ball walker), ``mujoxo``
(tic-tac-toe) and ``mujogo`` (Go), both with the Jaco arm. Unknown names
raise `ValueError` listing the valid ones.
"""

from __future__ import annotations

from typing import Callable

from hier_agents.estimators import BoardEstimator, EntityLayerEstimator, GridRoundingEstimator
from hier_agents.option_layer import ModularAgent


def family(env_name: str) -> str:
    """``"mujoban"``, ``"mujoxo"`` or ``"mujogo"`` for an environment name."""
    prefix = env_name.split("/", 1)[0]
    if prefix not in ("mujoban", "mujoxo", "mujogo"):
        raise ValueError(f"no modular agent for {env_name!r}; environment families: "
                         f"mujoban/*, mujoxo/*, mujogo/*")
    return prefix


def _sokoban_solver(env, seed):
    from abstract_planners.sokoban_solver import SokobanSolverPlanner
    return SokobanSolverPlanner(time_limit=10.0)


def _sokoban_random(env, seed):
    from abstract_planners.sokoban_random import RandomPlanner
    return RandomPlanner(seed=seed)


def _minimax(env, seed):
    from abstract_planners.tictactoe import MinimaxPlanner
    return MinimaxPlanner(seed=seed)


def _board_random(env, seed):
    from abstract_planners.board_random import RandomMovePlanner
    return RandomMovePlanner(seed=seed)


def _gnugo(env, seed):
    from abstract_planners.go import GnuGoPlanner
    game = env.task.game
    return GnuGoPlanner(10, board_size=game.size, komi=game.komi, seed=seed)


def _mcts(env, seed):
    from abstract_planners.go import MCTSPlanner
    return MCTSPlanner(1000, seed=seed)


def _ball(env, seed):
    from skills.ball import BallSkill
    return BallSkill()


def _arm(env, seed):
    from skills.arm import ArmTouchSkill
    return ArmTouchSkill()


Factory = Callable[..., object]

#: family -> name -> factory(env, seed); the first entry is the default.
PLANNERS: dict[str, dict[str, Factory]] = {
    "mujoban": {"sokoban-solver": _sokoban_solver, "random": _sokoban_random},
    "mujoxo": {"minimax": _minimax, "mcts": _mcts, "random": _board_random},
    "mujogo": {"gnugo": _gnugo, "mcts": _mcts, "random": _board_random},
}
SKILLS: dict[str, dict[str, Factory]] = {
    "mujoban": {"ball": _ball},
    "mujoxo": {"arm-touch": _arm},
    "mujogo": {"arm-touch": _arm},
}
ESTIMATORS: dict[str, dict[str, Factory]] = {
    "mujoban": {"entity-layer": lambda env, seed: EntityLayerEstimator(),
                "grid-rounding": lambda env, seed: GridRoundingEstimator()},
    "mujoxo": {"board": lambda env, seed: BoardEstimator()},
    "mujogo": {"board": lambda env, seed: BoardEstimator()},
}


def _pick(table: dict[str, dict[str, Factory]], kind: str, fam: str, name: str | None):
    options = table[fam]
    if name is None:
        return next(iter(options.values()))
    if name not in options:
        raise ValueError(f"unknown {kind} {name!r} for {fam}; valid: {sorted(options)}")
    return options[name]


def make_agent(env_name: str, env, *, planner: str | None = None, skill: str | None = None,
               estimator: str | None = None, seed: int | None = None,
               t_abs: int = 50) -> ModularAgent:
    """The modular agent for ``env`` (built from ``env_name``) with named parts."""
    fam = family(env_name)
    return ModularAgent(_pick(ESTIMATORS, "estimator", fam, estimator)(env, seed),
                        _pick(PLANNERS, "planner", fam, planner)(env, seed),
                        _pick(SKILLS, "skill", fam, skill)(env, seed), t_abs=t_abs)
