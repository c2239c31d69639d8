"""The `Estimator` role: what the agent sees, turned into an abstract state.

``estimate(env, timestep) -> state`` returns the planner's abstract state;
``reset(env, timestep)`` is called at every episode start (estimators may
remember, e.g. the player's previous cell). Every estimator here reads the
observation the environment gives any agent, so a pixel-based estimator can
replace it without touching planners or skills:

* `EntityLayerEstimator` (MuJoBan): the ``full_entity_layer`` observation
  (walls, targets, player, boxes per cell) -> `SokobanState`;
* `GridRoundingEstimator` (MuJoBan): the paper's appendix rule applied to
  world positions (each box rounded to its nearest cell first, then the
  player, who keeps its previous cell when it would share a box's cell);
* `BoardEstimator` (MuJoXO, MuJoGo): the ``move_history`` observation (the
  game record) replayed in OpenSpiel, checked against the ``board_state``
  markers.
"""

from __future__ import annotations

import abc

import numpy as np

from abstract_planners.sokoban import SokobanState


class EstimationError(RuntimeError):
    """The observation does not describe a consistent abstract state."""


class Estimator(abc.ABC):
    """Turns the current observation into an abstract state."""

    name = "estimator"

    def reset(self, env, timestep) -> None:
        """Called with the first timestep of every episode."""

    @abc.abstractmethod
    def estimate(self, env, timestep):
        """The abstract state now."""


def _cells(mask: np.ndarray) -> frozenset:
    return frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(mask)))


class EntityLayerEstimator(Estimator):
    """MuJoBan: `SokobanState` from the ``full_entity_layer`` observation."""

    name = "entity-layer"

    def estimate(self, env, timestep) -> SokobanState:
        layer = timestep.observation["full_entity_layer"]
        players = _cells(layer[..., 2])
        if len(players) != 1:
            raise EstimationError(f"the entity layer shows {len(players)} players")
        height, width = layer.shape[:2]
        return SokobanState(walls=_cells(layer[..., 0]), targets=_cells(layer[..., 1]),
                            boxes=_cells(layer[..., 3]), player=next(iter(players)),
                            height=height, width=width)


class GridRoundingEstimator(Estimator):
    """MuJoBan: the paper's rounding rule on the walker's and boxes' world positions.

    Walls and targets come from the level the task is playing (static, known
    to the agent as in the paper's abstract observation).
    """

    name = "grid-rounding"

    def __init__(self) -> None:
        self._player = None
        self._static = None

    def reset(self, env, timestep) -> None:
        self._player = None
        self._static = None

    def estimate(self, env, timestep) -> SokobanState:
        task = env.task
        if self._static is None:
            layer = timestep.observation["full_entity_layer"]
            self._static = (_cells(layer[..., 0]), _cells(layer[..., 1]), layer.shape[:2])
        walls, targets, (height, width) = self._static
        boxes = [task.world_to_cell(xy) for xy in task.box_positions()]
        player = task.world_to_cell(task.walker_position())
        if player in boxes:
            if self._player is None:
                raise EstimationError("the walker overlaps a box before any estimate")
            player = self._player
        self._player = player
        if len(set(boxes)) != len(boxes):
            raise EstimationError(f"two boxes round to one cell: {boxes}")
        return SokobanState(walls=walls, targets=targets, boxes=frozenset(boxes), player=player,
                            height=height, width=width)


class BoardEstimator(Estimator):
    """Board games: the game record (``move_history``) replayed in OpenSpiel.

    Raises `EstimationError` if the replayed board disagrees with the
    ``board_state`` markers.
    """

    name = "board"

    def __init__(self) -> None:
        self._games = {}

    def estimate(self, env, timestep):
        game = env.task.game
        key = (game.name, game.size, game.komi)
        if key not in self._games:
            self._games[key] = game.load()
        state = self._games[key].new_initial_state()
        for action in timestep.observation["move_history"]:
            if action < 0:
                break
            state.apply_action(int(action))
        if not np.array_equal(game.board_planes(state), timestep.observation["board_state"]):
            raise EstimationError("move_history and board_state disagree")
        return state
