"""MuJoBan estimators that read ground truth (privileged), and the paper's
rounding rule every MuJoBan estimator shares.

* `rounded_state`: the paper's appendix rule from continuous positions to a
  `SokobanState`: each box to its nearest cell, then the walker to its
  nearest cell unless that holds a box (then it keeps its previous cell).
* `OracleEstimator` (``oracle``): positions, velocities and heading read
  from the simulator, the task's own abstract cells; the upper bound, for
  debugging. Privileged.
* `EntityLayerEstimator` (``entity-layer``): the abstract state from the
  ``full_entity_layer`` observation (ground truth the environment computes
  from the simulator), the continuous part from the oracle. Privileged.
"""

from __future__ import annotations

import numpy as np

from abstract_planners.sokoban import SokobanState
from hier_agents.estimators.base import EstimationError, Estimator
from skills.scene import BallScene

__all__ = ["rounded_state", "OracleEstimator", "EntityLayerEstimator", "cells_of"]


def cells_of(mask: np.ndarray) -> frozenset:
    """The (row, col) cells where a 2D mask is true."""
    return frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(mask)))


def rounded_state(description, walls: frozenset, targets: frozenset, box_xy,
                  walker_xy, previous_player=None) -> tuple[SokobanState, tuple]:
    """(state, box cells in ``box_xy`` order) by the paper's rounding rule.

    Raises:
      EstimationError: two boxes round to one cell, a box or the walker
        rounds onto a wall, or the walker rounds onto a box with no previous
        cell to keep.
    """
    box_cells = tuple(description.world_to_cell(xy) for xy in np.asarray(box_xy, float))
    if len(set(box_cells)) != len(box_cells):
        raise EstimationError(f"two boxes round to one cell: {sorted(box_cells)}")
    on_walls = [c for c in box_cells if c in walls]
    if on_walls:
        raise EstimationError(f"box(es) round onto wall cells {on_walls}")
    player = description.world_to_cell(walker_xy)
    if player in box_cells or player in walls:
        if previous_player is None:
            raise EstimationError(f"the walker rounds onto cell {player} (a box or a wall) "
                                  f"before any estimate")
        player = previous_player
    height, width = description.grid_shape
    try:
        state = SokobanState(walls=walls, targets=targets, boxes=frozenset(box_cells),
                             player=player, height=height, width=width)
    except ValueError as exc:  # e.g. a box now where the walker's kept cell was
        raise EstimationError(f"no consistent grid: {exc}") from None
    return state, box_cells


class OracleEstimator(Estimator):
    """The simulator's own positions and the task's abstract cells.

    Privileged: it holds the real environment (given at construction, on
    purpose), not what the agent observes.
    """

    name = "oracle"
    privileged = True

    def __init__(self, simulator_env) -> None:
        self._env = simulator_env
        self._static = None

    def reset(self, description, timestep) -> None:
        task = self._env.task
        layer = np.asarray(task.observe(self._env.physics)["full_entity_layer"])
        self._static = (cells_of(layer[..., 0]), cells_of(layer[..., 1]), layer.shape[:2])

    def estimate(self, timestep) -> BallScene:
        task = self._env.task
        walls, targets, (height, width) = self._static
        box_cells, player = task.abstract_cells
        state = SokobanState(walls=walls, targets=targets, boxes=frozenset(box_cells),
                             player=tuple(player), height=height, width=width)
        return BallScene(state=state, walker_xy=task.walker_position().copy(),
                         walker_velocity=task.walker_velocity(), heading=task.walker_heading(),
                         box_xy=task.box_positions(), box_cells=tuple(box_cells))


class EntityLayerEstimator(OracleEstimator):
    """The abstract state from ``full_entity_layer``; positions from the oracle.

    Privileged (the entity layer is ground truth computed from the simulator).
    """

    name = "entity-layer"

    def estimate(self, timestep) -> BallScene:
        layer = timestep.observation.get("full_entity_layer")
        if layer is None:  # behind a boundary that strips it: read the simulator
            layer = self._env.task.observe(self._env.physics)["full_entity_layer"]
        layer = np.asarray(layer)
        players = cells_of(layer[..., 2])
        if len(players) != 1:
            raise EstimationError(f"the entity layer shows {len(players)} players")
        height, width = layer.shape[:2]
        state = SokobanState(walls=cells_of(layer[..., 0]), targets=cells_of(layer[..., 1]),
                             boxes=cells_of(layer[..., 3]), player=next(iter(players)),
                             height=height, width=width)
        scene = super().estimate(timestep)
        return BallScene(state=state, walker_xy=scene.walker_xy,
                         walker_velocity=scene.walker_velocity, heading=scene.heading,
                         box_xy=scene.box_xy, box_cells=scene.box_cells)
