"""Which planners, skills and estimators fit which environment, by name.

    agent = make_agent("mujoban/level5-pegs", env.description())             # defaults
    agent = make_agent("mujoban/level5-pegs", env.description(), planner="random")
    agent = make_agent("mujoban/level5-pegs", env.description(), estimator="oracle",
                       simulator=env)           # privileged: reads the simulator on purpose

Agents are built from the task's public description only; the privileged
estimators (``oracle``, ``entity-layer``) also need the simulator, given
explicitly as ``simulator``. The first name in each table is the default.

MuJoBan planners also take ``learned:PATH``: a policy over options trained
with ``python -m hier_agents.learning.train_options`` (a checkpoint file or run
directory) played by `abstract_planners.learned_options.OptionPolicyPlanner`;
``learned`` is the shipped one (``abstract_planners/learned/options.pt``:
the learned policy alone, no hand-written rule).

Families: ``mujoban`` (Sokoban states, the ball walker), ``mujoxo``
(tic-tac-toe) and ``mujogo`` (Go), both with the Jaco arm. Unknown names
raise `ValueError` listing the valid ones.
"""

from __future__ import annotations

from typing import Callable

from hier_agents.estimators import BoardEstimator, EntityLayerEstimator, OracleEstimator
from hier_agents.modular.agent import ModularAgent
from hier_agents.modular.families import family
from hier_agents.modular.options import T_ABS


def _sokoban_solver(description, seed):
    from abstract_planners.sokoban_solver import SokobanSolverPlanner
    return SokobanSolverPlanner(time_limit=10.0)


def _sokoban_time(description, seed):
    from abstract_planners.sokoban_time_solver import TimeSolverPlanner
    return TimeSolverPlanner(time_limit=10.0)


def _learned_options(path):
    def factory(description, seed):
        from abstract_planners.learned_options import OptionPolicyPlanner
        return OptionPolicyPlanner(path, seed=seed)
    return factory


class _PlannerTable(dict):
    """A family's planners by name, plus ``learned:PATH`` (any checkpoint of
    `hier_agents.learning.train_options`: a policy over options played as a planner)."""

    prefix = "learned:"

    def __contains__(self, name) -> bool:
        return dict.__contains__(self, name) or (isinstance(name, str) and name.startswith(
            self.prefix) and len(name) > len(self.prefix))

    def __getitem__(self, name):
        if not dict.__contains__(self, name) and name in self:
            return _learned_options(name[len(self.prefix):])
        return dict.__getitem__(self, name)


def _sokoban_random(description, seed):
    from abstract_planners.sokoban_random import RandomPlanner
    return RandomPlanner(seed=seed)


def _minimax(description, seed):
    from abstract_planners.tictactoe import MinimaxPlanner
    return MinimaxPlanner(seed=seed)


def _board_random(description, seed):
    from abstract_planners.board_random import RandomMovePlanner
    return RandomMovePlanner(seed=seed)


def _gnugo(description, seed):
    from abstract_planners.go import GnuGoPlanner
    return GnuGoPlanner(10, board_size=description.board_size, komi=description.komi, seed=seed)


def _mcts(description, seed):
    from abstract_planners.go import MCTSPlanner
    return MCTSPlanner(1000, seed=seed)


def _ball(description, seed):
    from skills.ball import BallSkill
    return BallSkill()


def _learned_ball(description, seed):
    from skills.learned import LearnedBallSkill
    return LearnedBallSkill()


def _arm(description, seed):
    from skills.arm import ArmTouchSkill
    return ArmTouchSkill()


def _learned_arm(description, seed):
    from skills.learned.arm import LearnedArmSkill
    return LearnedArmSkill()


Factory = Callable[..., object]

#: family -> name -> factory(description, seed); the first entry is the default.
PLANNERS: dict[str, dict[str, Factory]] = {
    "mujoban": _PlannerTable({"sokoban-solver:time": _sokoban_time,
                              "sokoban-solver": _sokoban_solver, "random": _sokoban_random,
                              "learned": _learned_options(None)}),
    "mujoxo": {"minimax": _minimax, "mcts": _mcts, "random": _board_random},
    "mujogo": {"gnugo": _gnugo, "mcts": _mcts, "random": _board_random},
}
SKILLS: dict[str, dict[str, Factory]] = {
    "mujoban": {"ball": _ball, "learned-ball": _learned_ball},
    "mujoxo": {"arm-touch": _arm, "learned-arm": _learned_arm},
    "mujogo": {"arm-touch": _arm, "learned-arm": _learned_arm},
}
def _camera(description, seed, simulator=None):
    from hier_agents.estimators.camera import CameraEstimator
    return CameraEstimator()


def _privileged(cls):
    def factory(description, seed, simulator=None):
        if simulator is None:
            raise ValueError(f"the {cls.name!r} estimator is privileged (it reads the "
                             f"simulator): pass the environment as simulator=env")
        return cls(simulator)
    factory.privileged = True
    return factory


#: family -> name -> factory(description, seed, simulator=None).
ESTIMATORS: dict[str, dict[str, Factory]] = {
    "mujoban": {"camera": _camera, "oracle": _privileged(OracleEstimator),
                "entity-layer": _privileged(EntityLayerEstimator)},
    "mujoxo": {"board": lambda description, seed, simulator=None: BoardEstimator()},
    "mujogo": {"board": lambda description, seed, simulator=None: BoardEstimator()},
}


def is_privileged(fam: str, estimator: str | None) -> bool:
    """Whether the named estimator (None: the default) reads the simulator."""
    return bool(getattr(_pick(ESTIMATORS, "estimator", fam, estimator), "privileged", False))


def estimator_name(fam: str, estimator: str | None) -> str:
    """The estimator's name (the default's when None)."""
    return estimator or next(iter(ESTIMATORS[fam]))


def env_overrides(env_name: str, estimator: str | None = None) -> dict:
    """`envs.load` overrides the estimator needs: every camera off except the
    ones it reads, at the frame size it asks for."""
    import envs
    fam = family(env_name)
    overrides = dict(envs.no_cameras(env_name))
    if estimator_name(fam, estimator) == "camera":
        from hier_agents.estimators.camera import CameraEstimator
        overrides.update(CameraEstimator.env_overrides)
    return overrides


def _pick(table: dict[str, dict[str, Factory]], kind: str, fam: str, name: str | None):
    options = table[fam]
    if name is None:
        return next(iter(options.values()))
    if name not in options:
        extra = (" or learned:PATH (a hier_agents.learning.train_options checkpoint)"
                 if isinstance(options, _PlannerTable) else "")
        raise ValueError(f"unknown {kind} {name!r} for {fam}; valid: {sorted(options)}{extra}")
    return options[name]


def make_agent(env_name: str, description, *, planner: str | None = None,
               skill: str | None = None, estimator: str | None = None,
               seed: int | None = None, t_abs: int = T_ABS, simulator=None) -> ModularAgent:
    """The modular agent for an environment named ``env_name`` with the public
    ``description`` (``env.description()``), with named parts.

    ``simulator`` (the environment itself) is needed only by the privileged
    estimators; nothing else receives it.
    """
    fam = family(env_name)
    return ModularAgent(_pick(ESTIMATORS, "estimator", fam, estimator)(description, seed,
                                                                       simulator),
                        _pick(PLANNERS, "planner", fam, planner)(description, seed),
                        _pick(SKILLS, "skill", fam, skill)(description, seed), t_abs=t_abs)
