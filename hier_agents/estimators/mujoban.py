"""MuJoBan estimators that read ground truth (privileged); the rounding rule
they share with the camera estimator is `hier_agents.estimators.grid`.

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
from hier_agents.estimators.grid import cells_of
from skills.scene import BallScene

__all__ = ["OracleEstimator", "EntityLayerEstimator"]


class OracleEstimator(Estimator):
    """The simulator's own positions and the task's abstract cells.

    Privileged: it holds the real environment (given at construction, on
    purpose), not what the agent observes.
    """

    name = "oracle"
    privileged = True

    def __init__(self, simulator_env) -> None:
        self._env = simulator_env
        # (walls, targets, grid shape): read by `reset`.
        self._static: tuple[frozenset, frozenset, tuple[int, ...]] | None = None

    def reset(self, description, timestep) -> None:
        task = self._env.task
        layer = np.asarray(task.observe(self._env.physics)["full_entity_layer"])
        self._static = (cells_of(layer[..., 0]), cells_of(layer[..., 1]), layer.shape[:2])

    def estimate(self, timestep) -> BallScene:
        task = self._env.task
        assert self._static is not None, "estimate called before reset"
        walls, targets, (height, width) = self._static
        box_cells, player = task.abstract_cells
        state = SokobanState(
            walls=walls,
            targets=targets,
            boxes=frozenset(box_cells),
            player=tuple(player),
            height=height,
            width=width,
        )
        return BallScene(
            state=state,
            walker_xy=task.walker_position().copy(),
            walker_velocity=task.walker_velocity(),
            heading=task.walker_heading(),
            box_xy=task.box_positions(),
            box_cells=tuple(box_cells),
        )


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
        state = SokobanState(
            walls=cells_of(layer[..., 0]),
            targets=cells_of(layer[..., 1]),
            boxes=cells_of(layer[..., 3]),
            player=next(iter(players)),
            height=height,
            width=width,
        )
        scene = super().estimate(timestep)
        return BallScene(
            state=state,
            walker_xy=scene.walker_xy,
            walker_velocity=scene.walker_velocity,
            heading=scene.heading,
            box_xy=scene.box_xy,
            box_cells=scene.box_cells,
        )
