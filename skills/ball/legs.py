"""The trajectory: a subgoal's moves (and look-ahead) as legs the ball drives.

`plan` replays a subgoal on its planned-from state, extends it with the
look-ahead and splits it into `Leg`s: walks, each maybe ending in a straight
chain of pushes (`make_leg`, in `skills.ball.leg_geometry`), preceded by a
push that centres a box the walker left short (`finish_leg`). See the
package docstring, *Trajectory*.
"""

from __future__ import annotations

import numpy as np

from abstract_planners.sokoban import DIRECTIONS
from skills.ball.config import BallConfig
from skills.ball.leg_geometry import Leg, make_leg, rebuild  # noqa: F401 (re-exported)
from skills.ball.paths import CONTACT, UNIT, ahead, walls_and_outside


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

    __slots__ = (
        "legs",
        "goal_boxes",
        "goal_player",
        "expected",
        "box_start",
        "needs_settle",
        "pushed_boxes",
    )
    legs: list[Leg]
    goal_boxes: frozenset
    goal_player: tuple
    expected: frozenset
    box_start: list[tuple[float, float]]
    needs_settle: bool
    pushed_boxes: set


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
    legs = _split(
        description, config, horizon, states, pushed, n_sub, box_xy, est_boxes, walls, here
    )
    # A box left short of its cell centre (the option layer may start a
    # new subgoal as soon as the estimate rounds it into its cell) is
    # first pushed on to the centre, if the walker is still behind it.
    finish = finish_leg(description, config, box_xy, est_boxes, here, walls | state.boxes)
    if finish is None and not moves:
        # Holding with a box off its cell centre and the walker not behind
        # it: walk round behind it and centre it.
        finish = centre_leg(
            description, config, box_xy, est_boxes, state, here, walls | state.boxes
        )
    if finish is not None and not moves:
        legs = [finish]
    elif finish is not None:
        first = legs[0]
        if not (
            first.push is not None and first.push[:2] == finish.push[:2] and len(first.seg) == 1
        ):
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
            raise IllegalMove(
                f"illegal move: {move!r} (move {k} of the subgoal) from player at {s.player}"
            )
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


def _split(
    description, config, horizon, states, pushed, n_sub, box_xy, est_boxes, walls, here
) -> list:
    """The horizon as legs: walks ending in a straight chain of pushes. A walk
    subgoal's last cell stays a vertex (its estimate must pass there)."""
    cells_of = [s.player for s in states]

    def _keep(lo, hi):
        end = n_sub
        return (end - lo,) if n_sub and pushed[n_sub - 1] is None and lo <= end < hi else ()

    legs = []
    start = 0
    k = 0
    while k < len(horizon):
        if pushed[k] is None:
            k += 1
            continue
        move = horizon[k]
        chain = 1
        while (
            k + chain < len(horizon)
            and horizon[k + chain] == move
            and pushed[k + chain] is not None
        ):
            chain += 1
        index = box_index(pushed[k], est_boxes)
        legs.append(
            make_leg(
                description,
                config,
                cells_of[start : k + 1],
                (index, move, pushed[k], chain),
                box_xy,
                walls | states[start].boxes,
                keep=_keep(start, k + 1),
                start=here if start == 0 else None,
            )
        )
        start = k + chain
        k += chain
    if start < len(horizon) or not legs:
        legs.append(
            make_leg(
                description,
                config,
                cells_of[start:],
                None,
                box_xy,
                walls | states[start].boxes,
                keep=_keep(start, len(horizon) + 1),
                start=here if start == 0 else None,
            )
        )
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
        return make_leg(
            description, config, [behind], (i, move, cell, 0), box_xy, blocked, start=here
        )
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
        return make_leg(description, config, path, (i, move, cell, 0), box_xy, blocked, start=here)
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
                if n in previous or n in blocked or not (0 <= n[0] < height and 0 <= n[1] < width):
                    continue
                previous[n] = cell
                nxt.append(n)
        frontier = nxt
    return None
