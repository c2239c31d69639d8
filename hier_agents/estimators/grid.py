"""The paper's rounding rule from continuous MuJoBan positions to the
abstract grid, shared by every MuJoBan estimator (observation-only and
privileged alike).

* `rounded_state`: each box to its nearest cell, then the walker to its
  nearest cell unless that holds a box (then it keeps its previous cell)
  (Mirza et al. 2020, appendix).
* `cells_of`: the cells of a boolean grid mask.
"""

from __future__ import annotations

import numpy as np

from abstract_planners.sokoban import SokobanState
from hier_agents.estimators.base import EstimationError

__all__ = ["rounded_state", "cells_of"]


def cells_of(mask: np.ndarray) -> frozenset:
    """The (row, col) cells where a 2D mask is true."""
    return frozenset((int(r), int(c)) for r, c in zip(*np.nonzero(mask)))


def rounded_state(
    description, walls: frozenset, targets: frozenset, box_xy, walker_xy, previous_player=None
) -> tuple[SokobanState, tuple]:
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
            raise EstimationError(
                f"the walker rounds onto cell {player} (a box or a wall) before any estimate"
            )
        player = previous_player
    height, width = description.grid_shape
    try:
        state = SokobanState(
            walls=walls,
            targets=targets,
            boxes=frozenset(box_cells),
            player=player,
            height=height,
            width=width,
        )
    except ValueError as exc:  # e.g. a box now where the walker's kept cell was
        raise EstimationError(f"no consistent grid: {exc}") from None
    return state, box_cells
