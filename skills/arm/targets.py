"""Where the arm touches for a move: which zones, in order (`touch_zones`:
a board point, a Go pass area, or a move game's piece then its
destination), and where each is (`touch_target`).

All from the public `envs.description.BoardDescription` (the points'
positions on the board's top, the pads' half-side, the pass zones beside the
board) and the game's rules (`envs.boards.games`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from envs.boards.games import BoardGame

#: Where the skill touches a pass area (the floor-level zones beside the Go
#: board): this far (m) out from the board's side edge, with this tolerance
#: (m) around it, between these distances (m) from the board's centre line
#: towards the arm.
PASS_OFFSET = 0.12
PASS_TOLERANCE = 0.07
PASS_Y_RANGE = (-0.02, 0.25)


@dataclass(frozen=True, eq=False)
class TouchTarget:
    """A point to touch: ``pad_top`` (world x, y, z of the sensitive
    surface's top) and ``tolerance`` (m, along x and y: the fingertips must
    land within this square around it)."""

    pad_top: np.ndarray
    tolerance: float


def touch_zones(description, state, action: int) -> tuple[int, ...] | None:
    """The zones to touch, in order, to play ``action`` from ``state`` (the
    game's `envs.boards.games.BoardGame.touches`: a point, the pass zone,
    or a move's piece then its destination); None if ``action`` is not
    legal there or not played by a touch."""
    game = BoardGame.from_description(description)
    try:
        return game.touches(state, int(action))
    except ValueError:
        return None


def touch_target(description, zone: int, tool: np.ndarray) -> TouchTarget | None:
    """The target of ``zone`` (a board point, or the pass zone whose id is
    the pass action) in the board of ``description``, the pass on the side
    of the tool point ``tool``; None if the zone is neither."""
    zone = int(zone)
    if description.pass_action is not None and zone == description.pass_action:
        return TouchTarget(pass_point(description, tool), PASS_TOLERANCE)
    if 0 <= zone < description.num_points:
        return TouchTarget(description.point_position(zone), float(description.pad_half))
    return None


def pass_point(description, tool: np.ndarray) -> np.ndarray:
    """The point of the pass area on the tool's side of the board to touch:
    `PASS_OFFSET` beside the board's edge (well clear of its squares), level
    with the tool within `PASS_Y_RANGE` (where the arm reaches it with the
    hand pointing down), at the pass area's top."""
    cx, cy = description.board_centre
    side = "left" if tool[0] < cx else "right"
    zone = description.pass_zones.get(side)
    if zone is None:
        raise ValueError("this board has no pass areas")
    point = np.array(zone["centre"], float)
    point[0] = cx + math.copysign(description.board_half + PASS_OFFSET, point[0] - cx)
    point[1] = np.clip(tool[1], cy + PASS_Y_RANGE[0], cy + PASS_Y_RANGE[1])
    return point
