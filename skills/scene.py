"""Scene estimates: what an `Estimator` hands to planners and skills.

A scene is an estimator's reading of one timestep: a continuous estimate of
the bodies that matter (poses, velocities) and the abstract state the
planner needs. Skills act on the scene and the subgoal, never on the
simulator (the observation boundary, `hier_agents.boundary`), so a camera
estimator and the privileged ``oracle`` are interchangeable under them.

Scenes are frozen; every ``estimate`` returns a new one (skills may compare
them by identity to notice a new estimate).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    import pyspiel

    from abstract_planners.sokoban import SokobanState

__all__ = ["BallScene", "ArmScene", "heading_from_orientation", "world_velocity"]


@dataclass(frozen=True, eq=False)
class BallScene:
    """MuJoBan: the walker and the boxes.

    Attributes:
      state: the abstract `SokobanState` (walls, targets, boxes, player cell)
        by the paper's rounding rule.
      walker_xy: world (x, y) of the ball's centre, metres.
      walker_velocity: world (vx, vy), m/s.
      heading: direction of the walker's face, radians from +x.
      box_xy: (num_boxes, 2) world (x, y) of the boxes' centres; the order is
        stable within an episode (box ``i`` stays box ``i``).
      box_cells: each box's nearest cell (row, col), in ``box_xy`` order.
    """

    state: SokobanState
    walker_xy: np.ndarray
    walker_velocity: np.ndarray
    heading: float
    box_xy: np.ndarray
    box_cells: tuple

    @property
    def abstract_cells(self) -> tuple[tuple, tuple[int, int]]:
        """(box cells in box order, player cell): the task's own convention."""
        return self.box_cells, self.state.player


@dataclass(frozen=True, eq=False)
class ArmScene:
    """Board games: the arm's joints and the game.

    Attributes:
      state: the OpenSpiel state of the game so far.
      moves: the game record (both players' actions, in order).
      qpos: (9,) arm and hand joint positions (the ``arm/joints_pos``
        observation; the qpos of the arm's own model).
      qvel: (9,) joint velocities.
      selected: move games: the point whose piece is selected for the half
        move in progress, or -1.
      agent: the agent's OpenSpiel player (0 or 1).
    """

    state: pyspiel.State
    moves: tuple[int, ...]
    qpos: np.ndarray
    qvel: np.ndarray
    selected: int = -1
    agent: int = 0


def heading_from_orientation(orientation) -> float:
    """The walker's face direction (radians from +x) from its
    ``walker/orientation`` observation (the root's 3x3 rotation, row-major):
    the face lies along the root's local +y axis."""
    r = np.asarray(orientation, float).reshape(3, 3)
    return math.atan2(r[1, 1], r[0, 1])


def world_velocity(orientation, velocimeter) -> np.ndarray:
    """World (vx, vy) from the ``walker/sensors_velocimeter`` reading (root
    frame) and the ``walker/orientation`` rotation."""
    r = np.asarray(orientation, float).reshape(3, 3)
    return (r @ np.asarray(velocimeter, float))[:2]
