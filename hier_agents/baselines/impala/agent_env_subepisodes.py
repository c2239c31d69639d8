"""The auxiliary task of `hier_agents.baselines.impala.agent_env.AgentEnv`:
setting up the planner and estimator, starting and checking sub-episodes
(targets, the planner planes and one-hot), building the agent's
observations and the last step's episode info (semantics in `agent_env`'s
module docstring).

`SubEpisodeMixin` is one of `AgentEnv`'s bases; it reads the attributes
`AgentEnv.__init__` and `AgentEnv.reset` set (``env``, ``family``,
``seed``, ``_cameras``, ``_proprio_keys``, ``_state_key``, ``_mujoban``,
``_return``, ``_steps``) and keeps the sub-episode's state.
"""

from __future__ import annotations

import numpy as np

from abstract_planners.base import NoPlanError
from hier_agents.baselines.impala.agent_env_spec import (_BOX, _PLAYER, EXPERT_PLANNER,
                                                         PLANNER_ACTIONS)
from hier_agents.estimators import EstimationError


class SubEpisodeMixin:
    """Planner set-up, sub-episodes, observations and episode info of `AgentEnv`."""

    def _setup_planning(self, condition: str, task) -> tuple:
        """The auxiliary task's planner and estimator (None for vanilla) and
        the planner-input buffers; returns (planner_shape or None,
        planner_action_dim)."""
        fam = self.family
        self.planner = self.estimator = None
        self._planning = condition != "vanilla"
        planner_shape, planner_action_dim = None, 0
        if self._planning:
            from hier_agents.modular.components import ESTIMATORS, PLANNERS

            planners = PLANNERS[fam]
            # The expert is the paper's: MuJoBan's exact Sokoban solver
            # (not the library's default, the execution-time planner).
            expert = planners.get(EXPERT_PLANNER.get(fam, ""),
                                  next(iter(planners.values())))
            factory = expert if condition == "expert-planner" else planners["random"]
            description = self.env.description()
            self.planner = factory(description, self.seed)
            # The paper's planner conditions read the ground-truth abstract
            # state: the privileged entity-layer estimator (board games:
            # the game record, observation-only).
            name = "entity-layer" if fam == "mujoban" else "board"
            self.estimator = ESTIMATORS[fam][name](description, self.seed, self.env)
            if fam == "mujoban":
                h, w = task.grid_shape
                planner_shape, planner_action_dim = (8, int(h), int(w)), len(PLANNER_ACTIONS)
            else:
                n = int(task.game.size)
                planner_shape = (6, n, n)
            self._planes = np.zeros(planner_shape, np.float32)
            self._onehot = np.zeros(planner_action_dim, np.float32)
        return planner_shape, planner_action_dim

    def _observe(self, observation) -> dict[str, np.ndarray]:
        obs = {"proprio": np.concatenate([observation[k] for k in self._proprio_keys],
                                         dtype=np.float32)}
        for name in self._cameras:
            obs[name] = np.ascontiguousarray(observation[name].transpose(2, 0, 1))
        if self._planning:
            obs["planner"] = self._planes.copy()
            if self._mujoban:
                obs["planner_action"] = self._onehot.copy()
        if self._state_key is not None:
            obs["state"] = observation[self._state_key].transpose(2, 0, 1).astype(np.float32)
        return obs

    def _check(self) -> tuple[bool, bool]:
        """(target reached, sub-episode over for another reason) after a step."""
        task = self.env.task
        if self._mujoban:
            cells, player = task.abstract_cells
            if self.subgoal is not None:
                target = self.subgoal.state
                return (player == target.player and frozenset(cells) == target.boxes), False
            # No target: try again once the abstract state changes.
            return False, (cells, player) != self._start_cells
        if task.moves_registered == self._start_registered:
            return False, False
        if self.subgoal is None:
            return False, True
        moves = task.moves
        move = moves[self._start_moves] if len(moves) > self._start_moves else None
        reached = move == int(self.subgoal.action)
        return reached, not reached

    def _start_subepisode(self, timestep) -> None:
        """Estimates the abstract state, asks for a target and builds the planner inputs."""
        task = self.env.task
        self._sub_steps = 0
        try:
            state = self.estimator.estimate(timestep).state
        except (EstimationError, ValueError):
            # Physics can put the rounded cells in a state no Sokoban board has
            # (two boxes in one cell, the walker on a box after a diagonal
            # shove): no target until the next sub-episode.
            state = None
        self.abstract_state = state
        subgoal = None
        if state is not None and not (state.is_solved() if self._mujoban
                                      else state.is_terminal()):
            try:
                subgoal = self.planner.plan(state)
            except (NoPlanError, ValueError):
                subgoal = None
        self.subgoal = subgoal
        if subgoal is None:
            self._unplanned += 1
        else:
            self._issued += 1
        planes, onehot = self._planes, self._onehot
        observation = timestep.observation
        if self._mujoban:
            self._start_cells = task.abstract_cells
            c = planes.shape[0] // 2
            planes[:c] = observation["full_entity_layer"].transpose(2, 0, 1)
            planes[c:] = planes[:c]
            onehot[:] = 0.0
            if subgoal is not None:
                target = subgoal.state
                planes[c + _PLAYER] = 0.0
                planes[c + _BOX] = 0.0
                planes[c + _PLAYER][target.player] = 1.0
                for cell in target.boxes:
                    planes[c + _BOX][cell] = 1.0
                onehot[PLANNER_ACTIONS.index(subgoal.action)] = 1.0
        else:
            self._start_registered = task.moves_registered
            self._start_moves = len(task.moves)
            planes[:3] = observation["board_state"].transpose(2, 0, 1)
            if subgoal is None:
                planes[3:] = planes[:3]
            else:
                planes[3:] = task.game.board_planes(subgoal.state).transpose(2, 0, 1)

    def _episode_info(self) -> dict:
        task, physics = self.env.task, self.env.physics
        terminated = bool(task.should_terminate_episode(physics))
        if self._mujoban:
            success = bool(task.solved)
        else:
            success = task.outcome == "win"  # a resignation by the opponent included
        info = {"episode_return": self._return, "episode_steps": self._steps,
                "success": success,
                "truncated": not terminated and self.env.step_count >= task.time_limit_steps}
        if self._planning:
            info.update(subgoals_issued=self._issued, subgoals_reached=self._reached,
                        subgoals_unplanned=self._unplanned)
        return info
