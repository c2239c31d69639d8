"""Estimators: observations -> scene estimates (`skills.scene`).

* MuJoBan: `CameraEstimator` (``camera``, the default: the top camera's
  frames and the walker's proprioception), `OracleEstimator` (``oracle``,
  privileged: the simulator's positions), `EntityLayerEstimator`
  (``entity-layer``, privileged: the environment's ground-truth grid);
* MuJoXO / MuJoGo / MuJoBoard: `BoardEstimator` (``board``: the game record
  and board observations, the arm's joint observations);
  `hier_agents.estimators.camera_board.BoardCameraEstimator` (``camera``,
  MuJoGo and MuJoBoard: the board from a camera, observation-only).
"""

from hier_agents.estimators.base import EstimationError, Estimator
from hier_agents.estimators.board import BoardEstimator
from hier_agents.estimators.camera import CameraEstimator
from hier_agents.estimators.grid import rounded_state
from hier_agents.estimators.mujoban import EntityLayerEstimator, OracleEstimator

__all__ = [
    "Estimator",
    "EstimationError",
    "BoardEstimator",
    "CameraEstimator",
    "OracleEstimator",
    "EntityLayerEstimator",
    "rounded_state",
]
