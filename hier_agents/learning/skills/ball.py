"""The learned ball skill's spec (`BALL_SPEC`) and its scene source.

The option is MuJoBan's walk-then-push subgoal (the Sokoban solver's
``next_push``: walk to a box, push it one or more cells;
`abstract_planners.sokoban_solver.SokobanSolverPlanner`), carried out by
`skills.learned.LearnedBallSkill` (the scripted geometry: legs, carrot,
speed profile, status; a learned [throttle, steer] controller).

`BallSceneSource` starts options from realistic scenes: states along solver
plans of generated levels (``mujoban/level1`` ... ``level5``, with and
without pegs) and real Boxoban levels (``boxoban/<file>[-pegs]``: the
shipped files in MuJoBan's level-5 arena). A start picks a source
uniformly, starts a fresh level and lets the *scripted* agent (the same
estimator, the solver, `skills.ball.BallSkill`, through the option runner
with the option layer's ``t_abs`` of 50) carry out a random number of
subgoals (uniform in 0..``max_skip``), so options start mid-level,
sometimes with the walker still rolling or a box left short by a cut-off
push. With probability ``p_continue`` a start instead continues the level
where the last option left it, if it was reached or cut off. Levels whose
remaining time is shorter than ``t_abs`` steps, or that the solver finds
deadlocked, are replaced.

Reward: +1 when reached (the skill's status: the estimated abstract state
equals the subgoal's and the pushed box is settled; or, when the push
solves the level and MuJoBan ends the episode first, the estimated boxes
equal the subgoal's); -1 when the option fails by disturbing the boxes
(``box disturbed``, ``box off line``, ``estimate deviates``, the runner's
``deviation``); -0.002 per control step.

``t_abs`` is 150 control steps (7.5 s) for training, not the option layer's
50: a walk-then-push subgoal on a 10x10 level-5 board takes the scripted
skill 26 steps at the median and 94 at the 95th percentile (the option
layer cuts it at 50 and re-plans the same trajectory), so at 50 steps even
the scripted skill reaches only ~65% of them in one option.

Estimators: ``oracle`` (the default for training: privileged, reads the
simulator, fast) or ``camera`` (observation-only: the top camera and
proprioception).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hier_agents.learning.skill_spec import OptionStart, SkillSpec
from hier_agents.modular.families import FAMILIES
from skills.learned.ball import POLICY_PATH

if TYPE_CHECKING:
    from dm_env import TimeStep

__all__ = [
    "BALL_SPEC",
    "BallSceneSource",
    "TRAIN_SOURCES",
    "HELDOUT_SOURCES",
    "make_source_env",
    "TRAIN_T_ABS",
]

#: The default training mixture: generated L1-L5 with and without pegs and
#: the shipped Boxoban files (with and without pegs).
TRAIN_SOURCES = tuple(f"mujoban/level{d}{p}" for d in range(1, 6) for p in ("", "-pegs")) + (
    "boxoban/unfiltered-valid-000",
    "boxoban/unfiltered-valid-000-pegs",
    "boxoban/medium-valid-000-pegs",
)
#: Held-out evaluation: level-5 with pegs (other seeds than training).
HELDOUT_SOURCES = ("mujoban/level5-pegs",)
#: The training cut-off of a ball option (control steps; module docstring).
TRAIN_T_ABS = 150


def make_source_env(source: str, seed: int, estimator: str = "oracle"):
    """The MuJoBan environment of a scene source (``mujoban/<name>`` or
    ``boxoban/<file>[-pegs]``) with the cameras the estimator reads."""
    import envs
    from envs.mujoban.levels import BOXOBAN_DIR
    from hier_agents.modular.components import env_overrides

    cameras = env_overrides("mujoban/level1", estimator)
    if source.startswith("boxoban/"):
        stem = source[len("boxoban/") :]
        pegs = stem.endswith("-pegs")
        stem = stem[: -len("-pegs")] if pegs else stem
        path = BOXOBAN_DIR / f"{stem}.txt"
        if not path.exists():
            raise ValueError(f"{source}: no level file {path}")
        base = "mujoban/level5-pegs" if pegs else "mujoban/level5"
        return envs.load(base, seed=seed, levels=str(path), **cameras)
    return envs.load(source, seed=seed, **cameras)


class _Counted:
    """The environment as an option sees it: ``step`` counts simulated steps
    and keeps the level's last timestep."""

    def __init__(self, env, level: "_Level", source: "BallSceneSource") -> None:
        self._env, self._level, self._source = env, level, source

    def step(self, action):
        self._source.sim_steps += 1
        self._level.timestep = self._env.step(action)
        return self._level.timestep

    def description(self):
        return self._env.description()


class _Level:
    """One scene source's environment, estimator and solver."""

    def __init__(self, name: str, seed: int, estimator: str, owner: "BallSceneSource"):
        from abstract_planners.sokoban_solver import SokobanSolverPlanner
        from hier_agents.modular.components import ESTIMATORS

        self.name = name
        self.env = make_source_env(name, seed, estimator)
        self.description = self.env.description()
        self.estimator = ESTIMATORS["mujoban"][estimator](self.description, seed, self.env)
        self.planner = SokobanSolverPlanner(time_limit=5.0)
        self.counted = _Counted(self.env, self, owner)
        self.timestep: TimeStep | None = None


class BallSceneSource:
    """Option starts for the ball skill (module docstring); a `SceneSource`."""

    def __init__(
        self,
        seed: int,
        estimator: str = "oracle",
        *,
        sources=TRAIN_SOURCES,
        t_abs: int = TRAIN_T_ABS,
        max_skip: int = 6,
        p_continue: float = 0.7,
    ):
        from skills.ball import BallSkill

        self.sources = tuple(sources)
        self.estimator = estimator
        self.t_abs, self.max_skip, self.p_continue = int(t_abs), int(max_skip), float(p_continue)
        self._seed_rng = np.random.default_rng(seed)
        self._levels: dict[str, _Level] = {}
        self._level: _Level | None = None
        self._alive = False
        self._scripted = BallSkill()
        self.sim_steps = 0

    def _get(self, name: str) -> _Level:
        level = self._levels.get(name)
        if level is None:
            seed = int(self._seed_rng.integers(2**31))
            level = self._levels[name] = _Level(name, seed, self.estimator, self)
        return level

    def _estimate(self, level: _Level):
        from hier_agents.estimators.base import EstimationError

        try:
            return level.estimator.estimate(level.timestep)
        except EstimationError:
            return None

    def _skip(self, level: _Level, n: int) -> bool:
        """Runs the scripted agent for ``n`` subgoals; False if the level ended."""
        from hier_agents.modular.options import run_option

        assert level.timestep is not None  # start() reset the level
        for _ in range(n):
            scene = self._estimate(level)
            if scene is None or level.timestep.last() or scene.state.is_solved():
                return scene is not None and not level.timestep.last()
            subgoal = level.planner.next_push(scene.state)
            run_option(
                level.counted,
                level.estimator,
                self._scripted,
                subgoal,
                level.timestep,
                adapter=FAMILIES["mujoban"],
                scene=scene,
            )
            if level.timestep.last():
                return False
        return True

    def start(self, rng: np.random.Generator) -> OptionStart | None:
        from abstract_planners.base import NoPlanError

        if not (self._alive and rng.random() < self.p_continue):
            level = self._level = self._get(self.sources[int(rng.integers(len(self.sources)))])
            level.timestep = level.env.reset()
            level.estimator.reset(level.description, level.timestep)
            level.planner.reset(int(rng.integers(2**31)))
            skip, fresh = int(rng.integers(self.max_skip + 1)), True
        else:
            assert self._level is not None  # alive: the last option's level goes on
            level = self._level
            assert level.timestep is not None  # and it was reset when it was picked
            skip = int(rng.random() < 0.3)
            fresh = skip > 0
        self._alive = False
        try:
            if not self._skip(level, skip):
                return None
            scene = self._estimate(level)
            time_left = level.description.time_limit_steps - level.env.step_count
            if (
                scene is None
                or level.timestep.last()
                or scene.state.is_solved()
                or time_left < self.t_abs
            ):
                return None
            subgoal = level.planner.next_push(scene.state)
        except NoPlanError:
            return None
        return OptionStart(
            level.counted,
            level.estimator,
            level.description,
            level.timestep,
            scene,
            subgoal,
            source=level.name,
            fresh=fresh,
        )

    def end(self, succeeded_or_cut_off: bool) -> None:
        self._alive = bool(succeeded_or_cut_off)

    def close(self) -> None:
        for level in self._levels.values():
            level.estimator.close()
            level.env.close()
        self._levels, self._level = {}, None


def make_ball_skill(policy=None):
    """The learned ball skill; ``policy=None``: record-only (the environment's mode)."""
    from skills.learned.ball import LearnedBallSkill

    return LearnedBallSkill(policy, record_only=policy is None)


def _train_scenes(seed: int, estimator: str = "oracle") -> BallSceneSource:
    return BallSceneSource(seed, estimator)


def _heldout_scenes(seed: int, estimator: str = "oracle") -> BallSceneSource:
    return BallSceneSource(seed, estimator, sources=HELDOUT_SOURCES, p_continue=0.0)


BALL_SPEC = SkillSpec(
    name="ball",
    skill_name="learned-ball",
    make_skill=make_ball_skill,
    scenes=_train_scenes,
    heldout=_heldout_scenes,
    checkpoint=POLICY_PATH,
    t_abs=TRAIN_T_ABS,
    estimators=("oracle", "camera"),
    family="mujoban",
    penalties={
        "box disturbed": -1.0,
        "box off line": -1.0,
        "estimate deviates": -1.0,
        "deviation": -1.0,
    },
    step_cost=-0.002,
)
