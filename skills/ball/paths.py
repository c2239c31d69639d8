"""Paths on the grid: the bodies' sizes, grid <-> world points, clearance
tests, string pulling and corner arcs.

Grid points are (row, col) floats (cell centres at integers); world points
are (x, y) metres. Clearances on the grid are in cells.
"""

from __future__ import annotations

import math

from abstract_planners.sokoban import DIRECTIONS

#: Half the side of a box and the ball's radius, metres (envs.mujoban.props).
BOX_HALF = 0.4
BALL_RADIUS = 0.2
#: Distance from a peg's axis to its corners (envs.mujoban.arena).
PEG_RADIUS = 0.05
#: Distance between the walker's and the box's centres when they touch.
CONTACT = BOX_HALF + BALL_RADIUS

#: World unit vector (x, y) of each move: rows grow downwards, y upwards.
UNIT = {m: (float(dc), float(-dr)) for m, (dr, dc) in DIRECTIONS.items()}

#: Clearance (cells) kept between the ball's centre and blocked cells when
#: cutting corners: the ball's radius plus a margin.
MARGIN = 0.3


class GridFrame:
    """Grid (row, col) <-> world (x, y) for a grid of ``shape`` cells of ``size`` metres."""

    __slots__ = ("size", "ox", "oy")

    def __init__(self, shape, size: float) -> None:
        h, w = shape
        self.size = size
        self.ox, self.oy = (w - 1) / 2.0, (h - 1) / 2.0

    def to_world(self, p):
        return ((p[1] - self.ox) * self.size, (self.oy - p[0]) * self.size)

    def to_grid(self, q):
        return (self.oy - q[1] / self.size, q[0] / self.size + self.ox)


def walls_and_outside(state) -> frozenset:
    """The state's walls plus a ring of cells just outside its grid."""
    ring = set(state.walls)
    for r in range(-1, state.height + 1):
        ring.add((r, -1))
        ring.add((r, state.width))
    for c in range(-1, state.width + 1):
        ring.add((-1, c))
        ring.add((state.height, c))
    return frozenset(ring)


def ahead(cell, move):
    """The cell next to ``cell`` in direction ``move``."""
    dr, dc = DIRECTIONS[move]
    return (cell[0] + dr, cell[1] + dc)


def point_clear(p, blocked, margin, peg=0.0) -> bool:
    """Whether grid point ``p`` = (row, col) is at least ``margin`` from every
    blocked cell and ``peg`` from every grid intersection (when pegs stand there)."""
    r, c = p
    R, C = round(r), round(c)
    if (R, C) in blocked:
        return False
    dr, dc = r - R, c - C
    if peg > 0.0 and (0.5 - abs(dr)) ** 2 + (0.5 - abs(dc)) ** 2 < peg * peg:
        return False
    edge = 0.5 - margin
    sr = 1 if dr > 0 else -1
    sc = 1 if dc > 0 else -1
    near_r = abs(dr) > edge
    near_c = abs(dc) > edge
    if near_r and (R + sr, C) in blocked:
        return False
    if near_c and (R, C + sc) in blocked:
        return False
    if near_r and near_c and (R + sr, C + sc) in blocked:
        if (0.5 - abs(dr)) ** 2 + (0.5 - abs(dc)) ** 2 < margin * margin:
            return False
    return True


def segment_clear(a, b, blocked, margin=MARGIN, step=0.05, peg=0.0) -> bool:
    """Whether every point of grid segment ``a``-``b`` (sampled every ``step``
    cells) is `point_clear`."""
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    n = max(1, int(length / step) + 1)
    for k in range(n + 1):
        f = k / n
        if not point_clear(
            (a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f), blocked, margin, peg
        ):
            return False
    return True


def string_pull(points, blocked, keep=(), peg=0.0) -> list:
    """Fewer vertices: each vertex joined to the farthest later one in clear sight.

    Vertices whose index is in ``keep`` (and the last) are never skipped.
    """
    out = [points[0]]
    i = 0
    n = len(points)
    keep = set(keep)
    while i < n - 1:
        best = i + 1
        j = i + 2
        while j < n and best not in keep:
            if segment_clear(points[i], points[j], blocked, peg=peg):
                best = j
                j += 1
            else:
                break
        out.append(points[best])
        i = best
    return out


def walk_points(
    frame: GridFrame, cells, blocked, *, keep=(), start=None, peg=0.0, smooth=True
) -> list:
    """World vertices of a walk through grid ``cells``.

    ``start`` (world (x, y), the walker) replaces the first cell centre when
    it lies in that cell and is clear; with ``smooth`` the vertices are
    string-pulled (``keep``: indices that stay vertices).
    """
    grid = [(float(r), float(c)) for r, c in cells]
    if start is not None:
        here = frame.to_grid(start)
        if (round(here[0]), round(here[1])) == tuple(cells[0]) and point_clear(
            here, blocked, MARGIN, peg
        ):
            grid[0] = here
    if smooth:
        grid = string_pull(grid, blocked, keep, peg)
    return [frame.to_world(p) for p in grid]


def merge_collinear(pts, direction=(1.0, 0.0)) -> list:
    """``pts`` without repeated points and with collinear runs merged; a
    single point becomes a tiny segment along ``direction`` (stay put)."""
    merged = [pts[0]]
    for p in pts[1:]:
        if math.hypot(p[0] - merged[-1][0], p[1] - merged[-1][1]) < 1e-6:
            continue
        if len(merged) >= 2:
            ax, ay = merged[-2]
            bx_, by_ = merged[-1]
            cross = (bx_ - ax) * (p[1] - by_) - (by_ - ay) * (p[0] - bx_)
            dot = (bx_ - ax) * (p[0] - bx_) + (by_ - ay) * (p[1] - by_)
            if abs(cross) < 1e-6 and dot > 0:
                merged[-1] = p
                continue
        merged.append(p)
    if len(merged) == 1:
        ux, uy = direction
        merged.insert(0, (merged[0][0] - 1e-6 * ux, merged[0][1] - 1e-6 * uy))
    return merged


def arc(vertex, a, b, theta, radius, turn, step=0.1) -> list:
    """Points of the arc of ``radius`` tangent to the lines into and out of ``vertex``."""
    vx, vy = vertex
    t = radius * math.tan(theta / 2.0)
    sx, sy = vx - a[0] * t, vy - a[1] * t
    cx, cy = sx - a[1] * radius * turn, sy + a[0] * radius * turn
    phi = math.atan2(sy - cy, sx - cx)
    n = max(2, int(math.ceil(theta * radius / step)))
    return [
        (
            cx + radius * math.cos(phi + turn * theta * i / n),
            cy + radius * math.sin(phi + turn * theta * i / n),
        )
        for i in range(n + 1)
    ]


def widest_arc(frame: GridFrame, vertex, a, b, theta, radius, blocked, peg, peg_touch):
    """The widest clear arc round the corner at world ``vertex`` (unit
    directions ``a`` in, ``b`` out, turning by ``theta``), trying ``radius``
    and 0.7 times smaller ones down to 0.1 cells: (points, radius), or None.

    Clear: every point keeps `MARGIN` from blocked cells and ``peg`` from
    pegs and, since the pursuit cuts inside fast arcs, the chord keeps the
    ball's radius from blocked cells and ``peg_touch`` from pegs.
    """
    size = frame.size
    to_grid = frame.to_grid
    turn = 1.0 if a[0] * b[1] - a[1] * b[0] > 0 else -1.0
    while radius >= 0.1 * size:
        points = arc(vertex, a, b, theta, radius, turn)
        if all(point_clear(to_grid(q), blocked, MARGIN, peg) for q in points) and segment_clear(
            to_grid(points[0]), to_grid(points[-1]), blocked, BALL_RADIUS / size, peg=peg_touch
        ):
            return points, radius
        radius *= 0.7
    return None
