"""The learned arm touch skill's spec (`ARM_SPEC`) and its scene source.

`ArmSceneSource` makes option starts from realistic mid-game positions of
MuJoXO and MuJoGo: it plays games (``mujoxo/optimal``, ``mujoxo/mixture``,
``mujogo/7x7``; the environments' own opponents reply) and offers each of
the agent's turns as a start. A fresh game first fast-forwards a random
number of the agent's moves (uniform in 0..``max_skip``) with the scripted
`skills.arm.ArmTouchSkill` and the family's default planner (minimax, GNU Go
level 10). The subgoal of a start is the default planner's move with
probability ``p_planner``, else a uniformly random legal point (so every
point is covered); in Go also the pass with probability ``p_pass`` (never
a second pass in a row, which the environment ignores). After an option
the game goes on from where it ended (the environment puts the arm at a
random pose above the board after every registered move, as in the agent's
games; a cut-off or failed touch leaves the arm where it was); an ended
game is replaced by a fresh one.

The option runner steps ``OptionStart.env`` (a thin recorder of the
environment: ``step``, ``description``); ``sim_steps`` counts every control
step simulated, fast-forwards included. Environments have no cameras; the
estimator is the observation-only `hier_agents.estimators.BoardEstimator`
(``"board"``). Training and held-out sources differ by seed only
(`HELDOUT_SEED_OFFSET`).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from hier_agents.learning.skill_spec import OptionStart, SkillSpec
from skills.learned.arm import POLICY_PATH

if TYPE_CHECKING:
    from dm_env import TimeStep

    from skills.arm import ArmTouchSkill

__all__ = [
    "ARM_SPEC",
    "ArmSceneSource",
    "TRAIN_SOURCES",
    "SOURCE_WEIGHTS",
    "HELDOUT_SEED_OFFSET",
    "make_arm_skill",
]

#: The games options start in, and how often each is picked.
TRAIN_SOURCES = ("mujoxo/optimal", "mujoxo/mixture", "mujogo/7x7")
SOURCE_WEIGHTS = (0.25, 0.25, 0.5)
#: Held-out sources: the same games, seeds offset by this.
HELDOUT_SEED_OFFSET = 10_000
#: Control steps the scripted fast-forward may spend on one move.
_FF_STEPS = 60


class _Recorder:
    """The environment as the option runner sees it: ``step`` (counted, the
    last timestep kept), ``description``; anything else is forwarded."""

    def __init__(self, env, source: "ArmSceneSource"):
        self._env, self._source = env, source
        self.timestep: TimeStep | None = None

    def step(self, action):
        self.timestep = self._env.step(action)
        self._source.sim_steps += 1
        return self.timestep

    def description(self):
        return self._env.description()

    def __getattr__(self, name):
        return getattr(self._env, name)


class _Game:
    """One source environment with its estimator and planners."""

    def __init__(self, name: str, seed: int, estimator: str):
        import envs
        from hier_agents.estimators import BoardEstimator
        from hier_agents.modular.components import PLANNERS, family

        if estimator != "board":
            raise ValueError(f"the arm skill's scenes use the 'board' estimator, got {estimator!r}")
        self.name = name
        self.env = envs.load(name, seed=seed, **envs.no_cameras(name))
        self.description = self.env.description()
        self.estimator = BoardEstimator()
        fam = family(name)
        self.planner = next(iter(PLANNERS[fam].values()))(self.description, seed)
        self.timestep: TimeStep | None = None
        self.reset_pending = True

    def close(self) -> None:
        for part in (self.planner, self.env):
            close = getattr(part, "close", None)
            if close is not None:
                close()


class ArmSceneSource:
    """Option starts for the learned arm skill (module docstring).

    Args:
      seed: seeds the environments and planners (the caller's ``rng`` picks
        the sources, skips and subgoals).
      estimator: ``"board"`` (the only one).
      sources, weights: the games and their probabilities.
      max_skip: the most scripted moves a fresh game fast-forwards.
      p_planner: probability of the default planner's move as the subgoal.
      p_pass: Go: probability of the pass as the subgoal.
    """

    def __init__(
        self,
        seed: int = 0,
        estimator: str = "board",
        *,
        sources=TRAIN_SOURCES,
        weights=SOURCE_WEIGHTS,
        max_skip: int = 2,
        p_planner: float = 0.5,
        p_pass: float = 0.04,
    ):
        self.seed = int(seed)
        self.estimator_name = estimator
        self.sources = tuple(sources)
        weights = np.asarray(
            weights if len(weights) == len(self.sources) else np.ones(len(self.sources)), float
        )
        self.weights = weights / weights.sum()
        self.max_skip, self.p_planner, self.p_pass = int(max_skip), float(p_planner), float(p_pass)
        self.sim_steps = 0
        self._games: dict[str, _Game] = {}
        self._current: _Game | None = None
        self._recorder: _Recorder | None = None
        self._teacher: ArmTouchSkill | None = None

    # -- SceneSource ------------------------------------------------------------

    def start(self, rng: np.random.Generator) -> OptionStart | None:
        name = self.sources[int(rng.choice(len(self.sources), p=self.weights))]
        game = self._game(name)
        fresh = False
        if (
            self._current is game
            and self._recorder is not None
            and self._recorder.timestep is not None
        ):
            game.timestep = self._recorder.timestep  # where the last option left it
        if game.reset_pending or game.timestep is None or game.timestep.last():
            self._new_game(game, rng)
            fresh = True
        if game.timestep is None or game.timestep.last():
            return None
        scene = game.estimator.estimate(game.timestep)
        if scene.state.is_terminal():
            game.reset_pending = True
            return None
        subgoal = self._subgoal(game, scene, rng)
        if subgoal is None:  # no move the arm can make here
            game.reset_pending = True
            return None
        self._current = game
        self._recorder = _Recorder(game.env, self)
        return OptionStart(
            env=self._recorder,
            estimator=game.estimator,
            description=game.description,
            timestep=game.timestep,
            scene=scene,
            subgoal=subgoal,
            source=name,
            fresh=fresh,
        )

    def end(self, succeeded_or_cut_off: bool) -> None:
        # The game goes on from the option's last timestep either way (a
        # failed touch may have played another move; the game record says).
        if (
            self._current is not None
            and self._recorder is not None
            and self._recorder.timestep is not None
        ):
            self._current.timestep = self._recorder.timestep

    def close(self) -> None:
        for game in self._games.values():
            game.close()
        self._games.clear()
        self._current = self._recorder = None

    # -- internals ----------------------------------------------------------------

    def _game(self, name: str) -> _Game:
        if name not in self._games:
            index = self.sources.index(name)
            self._games[name] = _Game(name, self.seed * 97 + index, self.estimator_name)
        return self._games[name]

    def _new_game(self, game: _Game, rng) -> None:
        from skills.arm import ArmTouchSkill
        from skills.base import Status

        game.reset_pending = False
        game.timestep = game.env.reset()
        game.estimator.reset(game.description, game.timestep)
        game.planner.reset(int(rng.integers(2**31)))
        if self._teacher is None:
            self._teacher = ArmTouchSkill()
        skill = self._teacher
        for _ in range(int(rng.integers(self.max_skip + 1))):
            if game.timestep.last():
                return
            scene = game.estimator.estimate(game.timestep)
            if scene.state.is_terminal():
                return
            skill.reset(game.description, game.planner.plan(scene.state), scene)
            steps = 0
            while skill.status is Status.RUNNING and steps < _FF_STEPS and not game.timestep.last():
                action = skill.act(game.timestep, scene)
                if skill.status is not Status.RUNNING:
                    break
                game.timestep = game.env.step(action)
                self.sim_steps += 1
                steps += 1
                scene = game.estimator.estimate(game.timestep)

    def _subgoal(self, game: _Game, scene, rng):
        from abstract_planners.base import Subgoal

        state = scene.state
        legal = [int(a) for a in state.legal_actions()]
        pass_action = game.description.pass_action
        points = [a for a in legal if a != pass_action]
        can_pass = (
            pass_action is not None
            and pass_action in legal
            and not (len(scene.moves) >= 2 and scene.moves[-2] == pass_action)
        )
        if not points and not can_pass:
            return None
        if can_pass and (rng.random() < self.p_pass or not points):
            action = pass_action
        elif rng.random() < self.p_planner:
            subgoal = game.planner.plan(state)
            action = int(subgoal.action)
            if subgoal.info.get("resigned") or (action == pass_action and not can_pass):
                action = int(rng.choice(points)) if points else pass_action
        else:
            action = int(rng.choice(points))
        child = state.clone()
        child.apply_action(action)
        return Subgoal(action=action, state=child, info={"source": "scene"})


def make_arm_skill(policy=None):
    """The learned arm skill for training: record-only for ``policy=None``;
    otherwise driven by ``policy`` with teacher labels on (for DAgger)."""
    from skills.learned.arm import LearnedArmSkill

    if policy is None:
        return LearnedArmSkill(record_only=True)
    return LearnedArmSkill(policy, labels=True)


def _train_scenes(seed: int, estimator: str = "board") -> ArmSceneSource:
    return ArmSceneSource(seed, estimator)


def _heldout_scenes(seed: int, estimator: str = "board") -> ArmSceneSource:
    return ArmSceneSource(seed + HELDOUT_SEED_OFFSET, estimator)


#: The learned arm touch skill (``python -m hier_agents.learning.train_skill arm``).
ARM_SPEC = SkillSpec(
    name="arm",
    make_skill=make_arm_skill,
    scenes=_train_scenes,
    heldout=_heldout_scenes,
    checkpoint=POLICY_PATH,
    t_abs=50,
    estimators=("board",),
    family="mujoxo",
    success_reward=1.0,
    penalties={"wrong move": -1.0},
    step_cost=-0.002,
    skill_name="learned-arm",
)
