"""The trajectory: a subgoal's moves (and look-ahead) as legs the ball drives.

`plan` replays a subgoal on its planned-from state, extends it with the
look-ahead and splits it into `Leg`s: walks, each maybe ending in a straight
chain of pushes (`make_leg`), preceded by a push that centres a box the
walker left short (`finish_leg`). See the package docstring, *Trajectory*.
"""

from __future__ import annotations

import math

import numpy as np

from abstract_planners.sokoban import DIRECTIONS
from skills.ball.config import BallConfig
from skills.ball.paths import (BALL_RADIUS, CONTACT, PEG_RADIUS, UNIT, GridFrame, ahead,
                               merge_collinear, walk_points, walls_and_outside, widest_arc)


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


class IllegalMove(ValueError):
    """A subgoal move is not legal in the state it is replayed on."""


class Trajectory:
    """What `plan` makes of a subgoal.

    Attributes:
      legs: the `Leg`s, in order.
      goal_boxes, goal_player: the subgoal's abstract state.
      expected: box placements (frozensets of cells) the trajectory passes through.
      box_start: each box's (x, y) at the start.
      needs_settle: whether the subgoal ends where the trajectory ends (then
        success waits for the last leg to settle).
      pushed_boxes: indices of the boxes the legs push.
    """

    __slots__ = ("legs", "goal_boxes", "goal_player", "expected", "box_start",
                 "needs_settle", "pushed_boxes")


def plan(description, config: BallConfig, subgoal, scene) -> Trajectory:
    """The trajectory of ``subgoal`` from ``scene`` (a `skills.scene.BallScene`
    whose ``state`` the subgoal was planned from); raises `IllegalMove`."""
    state = scene.state
    action = subgoal.action
    # A move letter, a string of letters, or a tuple/list of letters.
    moves = tuple(action) if isinstance(action, (tuple, list, str)) else (action,)
    horizon, states, pushed = _horizon(state, moves, subgoal.plan, config.lookahead)
    n_sub = len(moves)
    out = Trajectory()
    out.goal_boxes = frozenset(subgoal.state.boxes)
    out.goal_player = tuple(subgoal.state.player)
    out.expected = frozenset(s.boxes for s in states)

    box_xy = np.asarray(scene.box_xy, float).tolist()
    est_boxes = scene.box_cells
    out.box_start = [tuple(b) for b in box_xy]
    here = tuple(float(v) for v in scene.walker_xy)
    walls = walls_and_outside(state)
    legs = _split(description, config, horizon, states, pushed, n_sub, box_xy, est_boxes,
                  walls, here)
    # A box left short of its cell centre (the option layer may start a
    # new subgoal as soon as the estimate rounds it into its cell) is
    # first pushed on to the centre, if the walker is still behind it.
    finish = finish_leg(description, config, box_xy, est_boxes, here, walls | state.boxes)
    if finish is None and not moves:
        # Holding with a box off its cell centre and the walker not behind
        # it: walk round behind it and centre it.
        finish = centre_leg(description, config, box_xy, est_boxes, state, here,
                            walls | state.boxes)
    if finish is not None and not moves:
        legs = [finish]
    elif finish is not None:
        first = legs[0]
        if not (first.push is not None and first.push[:2] == finish.push[:2]
                and len(first.seg) == 1):
            legs.insert(0, finish)
    # The walker stops where the horizon ends; the subgoal needs settling
    # only if it ends there too.
    out.needs_settle = n_sub == len(horizon)
    out.legs = legs
    out.pushed_boxes = {leg.push[0] for leg in legs if leg.push}
    return out


def _horizon(state, moves, plan, lookahead):
    """Replays ``moves`` on ``state``, then (if ``lookahead``) the look-ahead
    from ``plan``: after a walk, up to and including the next push; after a
    push, the pushes that continue it straight on.

    Returns (horizon moves, states (one more), per move the pushed box's
    cell or None); raises `IllegalMove`.
    """
    states = [state]
    pushed = []  # per move: the pushed box's cell, or None
    for k, move in enumerate(moves):
        s = states[-1]
        if move not in DIRECTIONS or not s.is_legal(move):
            raise IllegalMove(f"illegal move: {move!r} (move {k} of the subgoal) "
                              f"from player at {s.player}")
        pushed.append(ahead(s.player, move) if s.is_push(move) else None)
        states.append(s.apply(move))
    horizon = list(moves)
    if lookahead:
        plan = tuple(plan)
        j = 0
        if not moves:
            pass  # hold: centre the boxes, stay
        elif pushed[-1] is None:  # a walk: go on up to the next push
            while j < len(plan) and j < 64:
                s = states[-1]
                if plan[j] not in DIRECTIONS or not s.is_legal(plan[j]):
                    break
                is_push = s.is_push(plan[j])
                pushed.append(ahead(s.player, plan[j]) if is_push else None)
                states.append(s.apply(plan[j]))
                horizon.append(plan[j])
                j += 1
                if is_push:
                    break
        if pushed and pushed[-1] is not None:  # a push: go on while it goes on straight
            while j < len(plan) and plan[j] == horizon[-1]:
                s = states[-1]
                if not (s.is_legal(plan[j]) and s.is_push(plan[j])):
                    break
                pushed.append(ahead(s.player, plan[j]))
                states.append(s.apply(plan[j]))
                horizon.append(plan[j])
                j += 1
    return horizon, states, pushed


def _split(description, config, horizon, states, pushed, n_sub, box_xy, est_boxes, walls,
           here) -> list:
    """The horizon as legs: walks ending in a straight chain of pushes. A walk
    subgoal's last cell stays a vertex (its estimate must pass there)."""
    cells_of = [s.player for s in states]

    def _keep(lo, hi):
        end = n_sub
        return (end - lo,) if n_sub and pushed[n_sub - 1] is None and lo <= end < hi \
            else ()

    legs = []
    start = 0
    k = 0
    while k < len(horizon):
        if pushed[k] is None:
            k += 1
            continue
        move = horizon[k]
        chain = 1
        while k + chain < len(horizon) and horizon[k + chain] == move \
                and pushed[k + chain] is not None:
            chain += 1
        index = box_index(pushed[k], est_boxes)
        legs.append(make_leg(
            description, config, cells_of[start:k + 1], (index, move, pushed[k], chain), box_xy,
            walls | states[start].boxes, keep=_keep(start, k + 1),
            start=here if start == 0 else None))
        start = k + chain
        k += chain
    if start < len(horizon) or not legs:
        legs.append(make_leg(description, config, cells_of[start:], None, box_xy,
                             walls | states[start].boxes,
                             keep=_keep(start, len(horizon) + 1),
                             start=here if start == 0 else None))
    return legs


def box_index(cell, est_boxes) -> int:
    """The index of the box estimated in ``cell``, or -1 (then `make_leg`
    takes the box nearest the cell)."""
    for i, c in enumerate(est_boxes):
        if tuple(c) == tuple(cell):
            return i
    return -1


def _box_offsets(description, box_xy, est_boxes):
    """Per estimated box: (index, cell, (x, y), offset (x, y) from its cell centre)."""
    for i, (bx, by) in enumerate(box_xy):
        if i >= len(est_boxes):
            break
        cell = tuple(est_boxes[i])
        cx, cy = map(float, description.cell_centre(*cell))
        yield i, cell, (bx, by), (bx - cx, by - cy)


def finish_leg(description, config: BallConfig, box_xy, est_boxes, here, blocked):
    """A push leg that centres a box the walker left short, or None."""
    size = float(description.cell_size)
    px, py = here
    tol = config.finish_tol * size
    for i, cell, (bx, by), (ox, oy) in _box_offsets(description, box_xy, est_boxes):
        if max(abs(ox), abs(oy)) <= tol:
            continue
        if abs(ox) >= abs(oy):
            move = "L" if ox > 0 else "R"
        else:
            move = "D" if oy > 0 else "U"
        dx, dy = UNIT[move]
        along = (bx - px) * dx + (by - py) * dy
        lateral = abs((bx - px) * dy - (by - py) * dx)
        if not (0.3 < along < CONTACT + 0.6 * size and lateral < 0.35):
            continue
        dr, dc = DIRECTIONS[move]
        behind = (cell[0] - dr, cell[1] - dc)
        if behind in blocked:
            continue
        return make_leg(description, config, [behind], (i, move, cell, 0), box_xy, blocked,
                        start=here)
    return None


def centre_leg(description, config: BallConfig, box_xy, est_boxes, state, here, blocked):
    """A walk to behind a box further than ``finish_tol`` from its cell centre
    and the short push that centres it (the largest offset first), or None
    when every box is centred or none can be reached from behind."""
    tol = config.finish_tol * float(description.cell_size)
    offsets = []
    for i, cell, _, (ox, oy) in _box_offsets(description, box_xy, est_boxes):
        for off, move in ((ox, "L" if ox > 0 else "R"), (oy, "D" if oy > 0 else "U")):
            if abs(off) > tol:
                offsets.append((abs(off), i, cell, move))
    for _, i, cell, move in sorted(offsets, reverse=True):
        dr, dc = DIRECTIONS[move]
        behind = (cell[0] - dr, cell[1] - dc)
        if behind in blocked:
            continue
        path = walk_cells(state.player, behind, blocked, state.height, state.width)
        if path is None:
            continue
        return make_leg(description, config, path, (i, move, cell, 0), box_xy, blocked,
                        start=here)
    return None


def walk_cells(start, goal, blocked, height, width):
    """The shortest 4-connected path of cells from ``start`` to ``goal``
    avoiding ``blocked`` (both ends included), or None."""
    start, goal = tuple(start), tuple(goal)
    previous = {start: None}
    frontier = [start]
    while frontier:
        nxt = []
        for cell in frontier:
            if cell == goal:
                path = []
                while cell is not None:
                    path.append(cell)
                    cell = previous[cell]
                return path[::-1]
            for dr, dc in DIRECTIONS.values():
                n = (cell[0] + dr, cell[1] + dc)
                if n in previous or n in blocked or not (0 <= n[0] < height
                                                          and 0 <= n[1] < width):
                    continue
                previous[n] = cell
                nxt.append(n)
        frontier = nxt
    return None


def rebuild(description, config: BallConfig, leg: Leg, box_xy, start) -> Leg:
    """``leg`` built again from the walker's position ``start`` and the boxes' ``box_xy``."""
    cells, push, blocked, keep = leg.args
    return make_leg(description, config, cells, push, box_xy, blocked, keep=keep, start=start)


def make_leg(description, config: BallConfig, cells, push, box_xy, blocked, *, keep=(),
             start=None) -> Leg:
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
    pts = walk_points(frame, cells, blocked, keep=keep, start=start, peg=peg,
                      smooth=config.smooth)
    leg = Leg()
    leg.args = (cells, push, blocked, keep)
    leg.push = None
    chain = 0
    if push is not None:
        chain = push[3]
        leg.push, leg.cell_lat = _push_line(frame, pts, push, box_xy)
    merged = merge_collinear(pts, leg.push[1] if leg.push is not None else (1.0, 0.0))
    # The straight run before meeting the box: the last segment minus the
    # push, which is as long as the box's actual distance to its target (a
    # leg rebuilt mid-push starts with the box between cells).
    contact_run = push_run = None
    if push is not None:
        _, (ux, uy), (tx, ty), _, _ = leg.push
        bx, by = box_xy[leg.push[0]]
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
    if push is not None:
        # Meeting the box: the last segment's length minus the push itself.
        _, _, _, _, length, s_last = seg[-1]
        # No meeting speed for a ball already touching the box (a leg
        # rebuilt mid-push): braking there would let the box slide on alone.
        bx, by = box_xy[leg.push[0]]
        ux, uy = leg.push[1]
        touching = start is not None and \
            (bx - start[0]) * ux + (by - start[1]) * uy - CONTACT < 0.05
        if not touching:
            limits.append((s_last + max(0.0, length - push_run), config.contact_speed))
    else:
        limits.append((s, 0.0))
    leg.pts = dense
    leg.seg = seg
    leg.limits = limits
    return leg


def _push_line(frame: GridFrame, pts, push, box_xy):
    """Ends the walk ``pts`` (in place) on the push line through the box's
    actual centre, plus the push up to where the walker stands when the box
    is centred in its last cell; returns (the leg's ``push``, ``cell_lat``)."""
    size = frame.size
    index, move, cell, chain = push
    ux, uy = UNIT[move]
    cx, cy = frame.to_world(cell)
    if index < 0:  # nearest physical box to the cell
        index = min(range(len(box_xy)),
                    key=lambda i: (box_xy[i][0] - cx) ** 2 + (box_xy[i][1] - cy) ** 2)
    bx, by = box_xy[index]
    # The push line goes through the box's actual centre.
    lateral = by if ux else bx
    px, py = pts[-1]
    pts[-1] = (px, by) if ux else (bx, py)
    tx, ty = (cx + ux * size * chain, by) if ux else (bx, cy + uy * size * chain)
    pts.append((tx - ux * CONTACT, ty - uy * CONTACT))
    return (index, (ux, uy), (tx, ty), lateral, chain), (cy if ux else cx)


def _round_corners(frame: GridFrame, config: BallConfig, merged, blocked, peg, peg_touch,
                   contact_run):
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
            found = widest_arc(frame, (x1, y1), (ax, ay), (bx_, by_), theta, radius, blocked,
                               peg, peg_touch)
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
