"""One leg of the ball's trajectory: its geometry (`make_leg`: a polyline
through grid cells with rounded corners and speed limits, maybe ending in a
straight push) and the `Leg` it makes. Used by `skills.ball.legs` (which
re-exports these names); lengths in metres, positions world (x, y).
"""

from __future__ import annotations

import math

from skills.ball.config import BallConfig
from skills.ball.paths import (
    BALL_RADIUS,
    CONTACT,
    PEG_RADIUS,
    UNIT,
    GridFrame,
    merge_collinear,
    walk_points,
    widest_arc,
)

__all__ = ["Leg", "make_leg", "rebuild"]


class Leg:
    """One stretch of the trajectory: a polyline, maybe ending in a push.

    Attributes:
      pts: vertices (x, y) of the walker's path.
      seg: per segment (x0, y0, ux, uy, length, start arc length).
      limits: (arc length, speed) constraints.
      push: None, or (box index, (ux, uy) push direction, box target (x, y),
        lateral line coordinate, cells pushed).
      cell_lat: for a push, the lateral coordinate of the box's cell's centre line.
      total: path length, metres.
      args: how it was built (rebuilt from the walker's position when the
        leg before it ends).
    """

    __slots__ = ("pts", "seg", "limits", "push", "total", "args", "cell_lat")
    pts: list
    seg: list
    limits: list
    push: tuple | None
    total: float
    args: tuple
    cell_lat: float


def rebuild(description, config: BallConfig, leg: Leg, box_xy, start) -> Leg:
    """``leg`` built again from the walker's position ``start`` and the boxes' ``box_xy``."""
    cells, push, blocked, keep = leg.args
    return make_leg(description, config, cells, push, box_xy, blocked, keep=keep, start=start)


def make_leg(
    description, config: BallConfig, cells, push, box_xy, blocked, *, keep=(), start=None
) -> Leg:
    """A leg through ``cells`` (grid cells), maybe ending in ``push`` =
    (box index or -1, move, box cell, cells pushed).

    ``blocked``: cells the ball must keep clear of (walls, boxes);
    ``keep``: indices of cells that stay vertices; ``start``: the
    walker's (x, y), used as the first vertex when it is clear.
    """
    size = float(description.cell_size)
    frame = GridFrame(description.grid_shape, size)
    # Pegs stand at every interior grid intersection: cut no corner
    # closer than the ball's radius, the peg's and a margin to one.
    peg = peg_touch = 0.0
    if description.pegs:
        peg_touch = (BALL_RADIUS + PEG_RADIUS) / size
        peg = (BALL_RADIUS + PEG_RADIUS + config.peg_margin) / size
    pts = walk_points(frame, cells, blocked, keep=keep, start=start, peg=peg, smooth=config.smooth)
    leg = Leg()
    leg.args = (cells, push, blocked, keep)
    line = None  # the leg's push: set when ``push`` is given
    if push is not None:
        line, leg.cell_lat = _push_line(frame, pts, push, box_xy)
    leg.push = line
    merged = merge_collinear(pts, line[1] if line is not None else (1.0, 0.0))
    # The straight run before meeting the box: the last segment minus the
    # push, which is as long as the box's actual distance to its target (a
    # leg rebuilt mid-push starts with the box between cells).
    contact_run: float | None = None
    push_run = 0.0  # read only for a push, which sets it
    if line is not None:
        _, (ux, uy), (tx, ty), _, _ = line
        bx, by = box_xy[line[0]]
        push_run = max(0.0, (tx - bx) * ux + (ty - by) * uy)
        lx, ly = merged[-2]
        contact_run = math.hypot(merged[-1][0] - lx, merged[-1][1] - ly) - push_run
    dense, marks = _round_corners(frame, config, merged, blocked, peg, peg_touch, contact_run)
    seg = []
    s = 0.0
    starts = []
    for (x0, y0), (x1, y1) in zip(dense, dense[1:]):
        length = math.hypot(x1 - x0, y1 - y0)
        starts.append(s)
        if length < 1e-9:
            continue
        seg.append((x0, y0, (x1 - x0) / length, (y1 - y0) / length, length, s))
        s += length
    starts.append(s)
    leg.total = s
    limits = [(starts[i], v) for i, v in marks]
    if line is not None:
        # Meeting the box: the last segment's length minus the push itself.
        _, _, _, _, length, s_last = seg[-1]
        # No meeting speed for a ball already touching the box (a leg
        # rebuilt mid-push): braking there would let the box slide on alone.
        bx, by = box_xy[line[0]]
        ux, uy = line[1]
        touching = (
            start is not None and (bx - start[0]) * ux + (by - start[1]) * uy - CONTACT < 0.05
        )
        if not touching:
            limits.append((s_last + max(0.0, length - push_run), config.contact_speed))
    else:
        limits.append((s, 0.0))
    leg.pts = dense
    leg.seg = seg
    leg.limits = limits
    return leg


def _push_line(frame: GridFrame, pts, push, box_xy) -> tuple[tuple, float]:
    """Ends the walk ``pts`` (in place) on the push line through the box's
    actual centre, plus the push up to where the walker stands when the box
    is centred in its last cell; returns (the leg's ``push``, ``cell_lat``)."""
    size = frame.size
    index, move, cell, chain = push
    ux, uy = UNIT[move]
    cx, cy = frame.to_world(cell)
    if index < 0:  # nearest physical box to the cell
        index = min(
            range(len(box_xy)), key=lambda i: (box_xy[i][0] - cx) ** 2 + (box_xy[i][1] - cy) ** 2
        )
    bx, by = box_xy[index]
    # The push line goes through the box's actual centre.
    lateral = by if ux else bx
    px, py = pts[-1]
    pts[-1] = (px, by) if ux else (bx, py)
    tx, ty = (cx + ux * size * chain, by) if ux else (bx, cy + uy * size * chain)
    pts.append((tx - ux * CONTACT, ty - uy * CONTACT))
    return (index, (ux, uy), (tx, ty), lateral, chain), (cy if ux else cx)


def _round_corners(
    frame: GridFrame, config: BallConfig, merged, blocked, peg, peg_touch, contact_run
):
    """Rounds the corners of polyline ``merged``: the widest clear arc (radius
    <= ``max_radius``) that leaves each segment at most half its length (the
    first and last almost all of it; with a push, ``contact_run`` not None,
    the push line keeps a straight run before contact).

    Returns (dense polyline, [(index in it where a corner starts, its speed limit)]).
    """
    lengths = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(merged, merged[1:])]
    dense = [merged[0]]
    marks = []
    last = len(merged) - 2  # index of the last segment
    for k in range(1, len(merged) - 1):
        (x0, y0), (x1, y1), (x2, y2) = merged[k - 1], merged[k], merged[k + 1]
        ax, ay = (x1 - x0) / lengths[k - 1], (y1 - y0) / lengths[k - 1]
        bx_, by_ = (x2 - x1) / lengths[k], (y2 - y1) / lengths[k]
        cos_turn = max(-1.0, min(1.0, ax * bx_ + ay * by_))
        theta = math.acos(cos_turn)
        into_push = contact_run is not None and k == last
        found = None
        if 0.05 < theta < 2.2:
            t_in = lengths[k - 1] * (0.9 if k == 1 else 0.5)
            if into_push:
                t_out = contact_run - config.push_straight
            else:
                t_out = lengths[k] * (0.9 if k == last else 0.5)
            half = math.tan(theta / 2.0)
            radius = min(config.max_radius, t_in / half, t_out / half)
            found = widest_arc(
                frame, (x1, y1), (ax, ay), (bx_, by_), theta, radius, blocked, peg, peg_touch
            )
        if found is not None:
            points, radius = found
            v = min(math.sqrt(config.lateral_accel * radius), config.max_turn_rate * radius)
            marks.append((len(dense), min(v, config.cruise_speed)))
            dense.extend(points)
        else:
            if cos_turn < -0.3:
                v = 0.05  # a reversal: stop, then roll the other way
            else:
                base = config.push_turn_speed if into_push else config.corner_speed
                v = min(config.cruise_speed, base / math.sqrt(max(1e-9, 1.0 - cos_turn)))
            marks.append((len(dense), v))
            dense.append((x1, y1))
    dense.append(merged[-1])
    return dense, marks
