"""The MuJoBan ball skill: the rolling ball carries out Sokoban subgoals.

`BallSkill` (name ``"ball"``) executes the `Subgoal`s of
`abstract_planners.sokoban_solver.SokobanSolverPlanner`: one move letter
(``plan(state)``) or a tuple of letters, the walk to a box and its push
(``next_push(state)``). It is a closed-loop controller on the walker's
position, velocity and heading and on the box positions, all read from the
estimator's `skills.scene.BallScene` every control step (the observation
boundary: the skill never reads the simulator; with the ``camera``
estimator it acts on what the top camera and the walker's proprioception
show). Grid geometry comes from the task's public
`envs.description.MujobanDescription`. ~40 us of Python per ``act``; ~0.2 ms
per ``reset``.

Usage (the option layer's loop, `hier_agents.option_layer.run_option`)::

    skill = BallSkill()
    skill.reset(env.description(), subgoal, scene)   # scene: estimator.estimate(timestep)
    while skill.status is Status.RUNNING and steps < T_abs:
        timestep = env.step(skill.act(timestep, scene))
        scene = estimator.estimate(timestep)

An empty subgoal, ``Subgoal(action=(), state=state)``, means "hold": centre
any box the walker left short of its cell centre (e.g. a push cut off by the
option layer whose box already rounds onto its pad without covering it),
then stand still; it succeeds once the boxes are settled.

Trajectory
==========

At ``reset`` the subgoal's moves are replayed on the planned-from state and
extended with a look-ahead from ``subgoal.plan``: after a walk, up to and
including the next push; after a push, the pushes that continue it in the
same direction. The moves become *legs*: a walk, ending (for a push) on the
push line through the box's actual centre, up to where the walker stands
when the box is centred in its last cell. Pushes in one direction are one
leg, so the box is never stopped in between; re-planning between subgoals
(the option layer re-estimates at least every T_abs steps) rebuilds the same
trajectory from wherever the walker is.

A walk's cell centres are first joined by straight lines wherever the ball
keeps 0.3 cells (its radius plus 0.1) from every wall and box cell and, in
levels with pegs (a 45-degree square post, 0.05 m from its axis to its
corners, at every interior grid intersection, blocking the ball as well as
the boxes), 0.35 cells (the ball's radius, the peg's and 0.1 m) from every
grid intersection (so staircases become diagonals in open rooms without
pegs, never in corridors, and with pegs the ball stays near the cell-centre
lines), then every corner is rounded by the widest arc (radius <= 1 cell)
that is just as clear and whose chord keeps the ball's radius from them (and
the ball's plus the peg's radius from pegs: the pursuit cuts inside fast
arcs). A turn into a push line keeps a straight run of 0.3 m before the
contact. A box that the walker left short of its cell centre while standing
behind it (its push was cut off) is first pushed on to the centre.

Control
=======

*Steering*: pure pursuit on the trajectory (a carrot ``0.45 + 0.35 v``
metres ahead); the ball rolls either way (the face only sets the sign of the
roll command), so the drive direction is the one needing the smaller turn,
with hysteresis. A yaw-rate loop turns the head (feed-forward of the
measured steer deadband and gain, rate feedback): the head is torque
driven with a ~0.2 s lag, ~0.3 s per 90 degrees.

*Pushing*: boxes (half-size 0.4 m, 2.5 kg) slide without rotating on floor
friction 0.5 (~12 N; once not pushed they decelerate at ~4.9 m/s^2, from
1 m/s they coast ~0.1 m), and the ball meets them with friction 1, so a ball
moving sideways while in contact drags its box sideways. A box more than
0.05 m off its cell's centre line catches on the pegs ahead of it. The ball
meets the box on the push line through the box's actual centre (within
``align_gap`` of it, a ball more than ``align_tol`` (``finish_align_tol``
for the short push that centres a box left short) off that line backs off
and comes in again, the tolerance widening by itself per back-off, also
across re-plans of the same push) and, once touching, aims ``k_recentre`` times the box's
offset from its cell's centre line on the other side of that line: its
sideways motion drags the box back onto the line before the pegs can catch
it.

*Speed*: the minimum of the cruise speed and, for every constraint at path
distance ``s`` ahead with speed ``v_c`` (arcs ``sqrt(a_lat r)``, sharp
corners, the contact with the box, the end of a walk), ``sqrt(v_c^2 +
2 a s)``; while pushing, at most ``push_speed`` (1.5 m/s), and the box's
remaining distance ``r`` caps it at ``sqrt(2 a_push (r - lead))`` with
``a_push`` = 3.5 m/s^2, below the box's own floor deceleration, so the ball
stays in contact and steers the box to the end (faster pushes or planned
decelerations near 4.9 m/s^2 let boxes run on and miss the pad's 0.1-cell
tolerance). The box then stops within ``center_tol`` of its cell centre. The
target is scaled down with the heading error and tracked by a proportional
roll command with feed-forward. The ball meets the box at
``contact_speed`` (0.8 m/s) and pushing accelerates at only ~2.6 m/s^2:
one push takes ~1 s, each further cell of a straight push ~0.55 s.

Status
======

* SUCCESS when the scene's abstract cells (boxes as a set, and the player)
  equals the subgoal's state and, if the trajectory ends with the subgoal,
  the pushed box is settled (< 0.1 m/s) within ``center_tol`` (0.08 cells)
  of its cell centre, or the walker stands near its last cell. When the plan
  goes on the same way (the next push continues in the same direction, the
  walk continues) reaching the abstract state is enough, so the ball does
  not stop between subgoals.
* FAILURE, with ``failure_reason`` = ``"<kind>: <details>"``, kinds:
  ``illegal move`` (in the given state; at ``reset``), ``stuck`` (no
  progress for ``stuck_steps`` steps: blocked path, box against a wall or
  snagged on a peg), ``box disturbed`` (a box that should stay put moved more
  than ``disturb_tol``), ``box off line`` (the pushed box left its push line
  by 0.2 m), ``estimate deviates`` (the estimated boxes are none of the
  placements the trajectory passes through), ``box overshot`` (it settled
  outside its target cell), ``not reached`` (stopped, but the estimate never
  matched).

The skill keeps no state between ``reset`` calls except the walker's last
heading (for its yaw rate) and drive direction, forgotten when a timestep is
the first of an episode or the environment changes.
"""

from __future__ import annotations

import math

import numpy as np

from abstract_planners.sokoban import DIRECTIONS
from skills.base import Skill, Status

__all__ = ["BallSkill", "BOX_HALF", "BALL_RADIUS", "CONTACT"]

#: Half the side of a box and the ball's radius, metres (envs.mujoban.props).
BOX_HALF = 0.4
BALL_RADIUS = 0.2
#: Distance from a peg's axis to its corners (envs.mujoban.arena).
PEG_RADIUS = 0.05
#: Distance between the walker's and the box's centres when they touch.
CONTACT = BOX_HALF + BALL_RADIUS

_PI = math.pi
_TWO_PI = 2.0 * math.pi
#: World unit vector (x, y) of each move: rows grow downwards, y upwards.
_UNIT = {m: (float(dc), float(-dr)) for m, (dr, dc) in DIRECTIONS.items()}


def _wrap(angle: float) -> float:
    return (angle + _PI) % _TWO_PI - _PI


class _Leg:
    """One stretch of the trajectory: a polyline, maybe ending in a push.

    Attributes:
      pts: vertices (x, y) of the walker's path.
      seg: per segment (x0, y0, ux, uy, length, start arc length).
      limits: (arc length, speed) constraints.
      push: None, or (box index, (ux, uy) push direction, box target (x, y),
        lateral line coordinate, cells pushed).
      total: path length, metres.
      args: how it was built (rebuilt from the walker's position when the
        leg before it ends).
    """

    __slots__ = ("pts", "seg", "limits", "push", "total", "args", "cell_lat")


class BallSkill(Skill):
    """Closed-loop controller of MuJoBan's rolling ball (see the module docstring).

    Args:
      cruise_speed: top speed on straight walks, m/s.
      corner_speed: speed through a sharp (unrounded) 90-degree corner, m/s.
      push_turn_speed: speed through a sharp turn into a push line, m/s.
      contact_speed: speed when the ball meets the box, m/s.
      push_speed: top speed while pushing, m/s.
      decel: planned deceleration before corners, the box and stops, m/s^2
        (the ball brakes at ~8).
      push_decel: planned deceleration of the ball and the box it pushes.
      push_lead: the ball stops pushing this far (m) before the box centre
        reaches its target; the box slides the rest.
      center_tol: how far (cells) from its cell centre a settled box may be.
      stuck_steps: control steps without progress before failing.
      disturb_tol: metres a box that should stay put may move before failing.
      lookahead: extend the trajectory with ``subgoal.plan`` (module doc).
      smooth: join cells in clear sight and round corners (module doc);
        without it the ball follows the cell centres.

    The controller's gains are class attributes (``look_base``, ``k_heading``,
    ...), tuned on generated levels and Boxoban; change them on an instance.
    """

    name = "ball"

    #: Pure pursuit look-ahead: ``look_base + look_gain * speed`` metres.
    look_base = 0.45
    look_gain = 0.35
    #: Heading loop: desired yaw rate per radian of error (1/s), yaw-rate
    #: feedback (steer per rad/s), and the steer actuator's measured model:
    #: ~7.3 rad/s per unit command above a deadband of ~0.13.
    k_heading = 4.0
    k_rate = 0.12
    steer_gain = 7.3
    steer_deadband = 0.13
    max_yaw_rate = 6.5
    #: Roll loop: command per m/s of speed error, feed-forward per m/s, extra
    #: command while pushing (the box's floor friction).
    k_speed = 2.0
    k_speed_ff = 0.2
    push_bias = 0.15
    #: Below this cosine of the heading error the ball turns without rolling;
    #: above it the speed target scales up linearly.
    align_cos = 0.5
    #: Corner arcs: largest radius (cells), lateral acceleration (m/s^2) and
    #: yaw rate (rad/s) that set their speed, straight run (m) kept before
    #: meeting a box.
    max_radius = 1.0
    lateral_accel = 8.0
    max_turn_rate = 5.0
    push_straight = 0.3
    #: A box further than this (cells) from its cell centre, with the walker
    #: behind it, is first pushed on to the centre.
    finish_tol = 0.08
    #: Meeting a box: within ``align_gap`` metres of it, a ball more than
    #: ``align_tol`` metres off the push line (``finish_align_tol`` when
    #: centring a box left short: too short a push to steer the box back)
    #: backs off and comes in again.
    align_gap = 0.3
    align_tol = 0.125
    finish_align_tol = 0.04
    #: While pushing, the carrot sits ``k_recentre`` times the box's offset
    #: from its cell's centre line on the other side of it (at most
    #: ``max_recentre`` m), so the ball's sideways motion drags it back.
    k_recentre = 1.0
    max_recentre = 0.3
    #: Clearance (m) kept between the ball and a peg when cutting corners.
    peg_margin = 0.1

    def __init__(self, *, cruise_speed: float = 3.5, corner_speed: float = 1.4,
                 push_turn_speed: float = 0.5, contact_speed: float = 0.8,
                 push_speed: float = 1.5, decel: float = 7.0, push_decel: float = 3.5,
                 push_lead: float = 0.0, center_tol: float = 0.08, stuck_steps: int = 30,
                 disturb_tol: float = 0.15, lookahead: bool = True,
                 smooth: bool = True) -> None:
        super().__init__()
        self.cruise_speed = float(cruise_speed)
        self.corner_speed = float(corner_speed)
        self.push_turn_speed = float(push_turn_speed)
        self.contact_speed = float(contact_speed)
        self.push_speed = float(push_speed)
        self.decel = float(decel)
        self.push_decel = float(push_decel)
        self.push_lead = float(push_lead)
        self.center_tol = float(center_tol)
        self.stuck_steps = int(stuck_steps)
        self.disturb_tol = float(disturb_tol)
        self.lookahead = bool(lookahead)
        self.smooth = bool(smooth)
        self._description = None
        self._task = None
        self._prev_heading = None
        self._sign = 1.0
        self._legs: list[_Leg] = []
        self._backing = False
        self._backoffs = 0
        self._action = np.zeros(2)
        #: Set to a list to record per-step controller values (debugging):
        #: (step, leg, segment, x, y, heading, yaw rate, heading error, drive
        #: sign, target speed, speed, roll, steer, box distance to go).
        self.trace = None

    def __repr__(self) -> str:
        return (f"BallSkill(cruise_speed={self.cruise_speed}, push_speed={self.push_speed}, "
                f"stuck_steps={self.stuck_steps})")

    # -- reset: the trajectory ------------------------------------------------------

    def reset(self, description, subgoal, scene) -> None:
        """Starts executing ``subgoal`` (planned from ``scene``, a
        `skills.scene.BallScene`) in the task ``description``
        (`envs.description.MujobanDescription`)."""
        state = scene.state
        # Backing off from a box (see act) goes on across a re-plan that
        # pushes the same box the same way: the option layer may re-plan
        # every few steps, and the ball must not shuttle at the box.
        was_backing = None
        was_backing_now = self._backing
        backoffs = self._backoffs
        if self._legs and description is self._description and (self._backing or backoffs):
            old_push = self._legs[self._leg].push
            was_backing = old_push[:2] if old_push is not None else None
        self.status = Status.RUNNING
        self.failure_reason = None
        if description is not self._description:
            self._description = description
            self._prev_heading = None
            self._sign = 1.0
        task = self._task = description
        self._cell = float(task.cell_size)
        self._dt = float(task.control_timestep)
        self._legs = []
        self._leg = 0
        self._i = 0
        self._steps = 0
        self._best = math.inf
        self._since_best = 0
        self._settle = 0
        self._est_seen = None
        self._est_match = False
        self._prev_box = None
        self._touched = False
        self._backing = False

        action = subgoal.action
        # A move letter, a string of letters, or a tuple/list of letters.
        moves = tuple(action) if isinstance(action, (tuple, list, str)) else (action,)
        # Replay the subgoal's moves, then the look-ahead.
        states = [state]
        pushed = []  # per move: the pushed box's cell, or None
        for k, move in enumerate(moves):
            s = states[-1]
            if move not in DIRECTIONS or not s.is_legal(move):
                self._fail(f"illegal move: {move!r} (move {k} of the subgoal) "
                           f"from player at {s.player}")
                return
            pushed.append(_ahead(s.player, move) if s.is_push(move) else None)
            states.append(s.apply(move))
        n_sub = len(moves)
        horizon = list(moves)
        if self.lookahead:
            plan = tuple(subgoal.plan)
            j = 0
            if not moves:
                pass  # hold: centre the boxes, stay
            elif pushed[-1] is None:  # a walk: go on up to the next push
                while j < len(plan) and j < 64:
                    s = states[-1]
                    if plan[j] not in DIRECTIONS or not s.is_legal(plan[j]):
                        break
                    is_push = s.is_push(plan[j])
                    pushed.append(_ahead(s.player, plan[j]) if is_push else None)
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
                    pushed.append(_ahead(s.player, plan[j]))
                    states.append(s.apply(plan[j]))
                    horizon.append(plan[j])
                    j += 1
        self._goal_boxes = frozenset(subgoal.state.boxes)
        self._goal_player = tuple(subgoal.state.player)
        # Box placements the trajectory passes through (estimate sanity check).
        self._expected = frozenset(s.boxes for s in states)

        box_xy = np.asarray(scene.box_xy, float).tolist()
        est_boxes = scene.box_cells
        self._box_start = [tuple(b) for b in box_xy]

        # Split into legs: walks ending in a straight chain of pushes. A walk
        # subgoal's last cell stays a vertex (its estimate must pass there).
        cells_of = [s.player for s in states]
        walls = _walls_and_outside(state)
        here = tuple(float(v) for v in scene.walker_xy)

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
            index = self._box_index(pushed[k], est_boxes, box_xy)
            legs.append(self._make_leg(
                cells_of[start:k + 1], (index, move, pushed[k], chain), box_xy,
                walls | states[start].boxes, keep=_keep(start, k + 1),
                start=here if start == 0 else None))
            start = k + chain
            k += chain
        if start < len(horizon) or not legs:
            legs.append(self._make_leg(cells_of[start:], None, box_xy,
                                       walls | states[start].boxes,
                                       keep=_keep(start, len(horizon) + 1),
                                       start=here if start == 0 else None))
        # A box left short of its cell centre (the option layer may start a
        # new subgoal as soon as the estimate rounds it into its cell) is
        # first pushed on to the centre, if the walker is still behind it.
        finish = self._finish_leg(box_xy, est_boxes, here, walls | state.boxes)
        if finish is not None and not moves:
            legs = [finish]
        elif finish is not None:
            first = legs[0]
            if not (first.push is not None and first.push[:2] == finish.push[:2]
                    and len(first.seg) == 1):
                legs.insert(0, finish)
        # The walker stops where the horizon ends; the subgoal needs settling
        # only if it ends there too.
        self._needs_settle = n_sub == len(horizon)
        self._legs = legs
        self._pushed_boxes = {leg.push[0] for leg in legs if leg.push}
        self._backoffs = 0
        if was_backing is not None and legs[0].push is not None \
                and legs[0].push[:2] == was_backing:
            self._backing = was_backing_now
            self._backoffs = backoffs

    @staticmethod
    def _box_index(cell, est_boxes, box_xy) -> int:
        for i, c in enumerate(est_boxes):
            if tuple(c) == tuple(cell):
                return i
        return -1  # resolved against positions in _make_leg

    def _finish_leg(self, box_xy, est_boxes, here, blocked):
        """A push leg that centres a box the walker left short, or None."""
        task = self._task
        px, py = here
        tol = self.finish_tol * self._cell
        for i, (bx, by) in enumerate(box_xy):
            if i >= len(est_boxes):
                break
            cell = tuple(est_boxes[i])
            cx, cy = map(float, task.cell_centre(*cell))
            ox, oy = bx - cx, by - cy
            if max(abs(ox), abs(oy)) <= tol:
                continue
            if abs(ox) >= abs(oy):
                move = "L" if ox > 0 else "R"
            else:
                move = "D" if oy > 0 else "U"
            dx, dy = _UNIT[move]
            along = (bx - px) * dx + (by - py) * dy
            lateral = abs((bx - px) * dy - (by - py) * dx)
            if not (0.3 < along < CONTACT + 0.6 * self._cell and lateral < 0.35):
                continue
            dr, dc = DIRECTIONS[move]
            behind = (cell[0] - dr, cell[1] - dc)
            if behind in blocked:
                continue
            return self._make_leg([behind], (i, move, cell, 0), box_xy, blocked, start=here)
        return None

    def _make_leg(self, cells, push, box_xy, blocked, *, keep=(), start=None) -> _Leg:
        """A leg through ``cells`` (grid cells), maybe ending in ``push``.

        ``blocked``: cells the ball must keep clear of (walls, boxes);
        ``keep``: indices of cells that stay vertices; ``start``: the
        walker's (x, y), used as the first vertex when it is clear.
        """
        task = self._task
        h, w = task.grid_shape
        size = self._cell
        ox, oy = (w - 1) / 2.0, (h - 1) / 2.0

        def to_world(p):
            return ((p[1] - ox) * size, (oy - p[0]) * size)

        def to_grid(q):
            return (oy - q[1] / size, q[0] / size + ox)

        # Pegs stand at every interior grid intersection: cut no corner
        # closer than the ball's radius, the peg's and a margin to one.
        peg = peg_touch = 0.0
        if task.pegs:
            peg_touch = (BALL_RADIUS + PEG_RADIUS) / size
            peg = (BALL_RADIUS + PEG_RADIUS + self.peg_margin) / size
        grid = [(float(r), float(c)) for r, c in cells]
        if start is not None:
            here = (oy - start[1] / size, start[0] / size + ox)
            if (round(here[0]), round(here[1])) == tuple(cells[0]) \
                    and _point_clear(here, blocked, _MARGIN, peg):
                grid[0] = here
        if self.smooth:
            grid = _string_pull(grid, blocked, keep, peg)
        pts = [to_world(p) for p in grid]
        leg = _Leg()
        leg.args = (cells, push, blocked, keep)
        leg.push = None
        chain = 0
        if push is not None:
            index, move, cell, chain = push
            ux, uy = _UNIT[move]
            cx, cy = to_world(cell)
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
            leg.push = (index, (ux, uy), (tx, ty), lateral, chain)
            leg.cell_lat = cy if ux else cx
        # Merge collinear vertices and drop zero-length segments.
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
        if len(merged) == 1:  # stay put: a tiny segment (along the push, if any)
            ux, uy = leg.push[1] if leg.push is not None else (1.0, 0.0)
            merged.insert(0, (merged[0][0] - 1e-6 * ux, merged[0][1] - 1e-6 * uy))
        # Round the corners: the widest clear arc (radius <= max_radius) that
        # leaves each segment at most half its length (the first and last
        # almost all of it; a push line keeps a straight run before contact).
        contact_run = None
        if push is not None:
            lx, ly = merged[-2]
            contact_run = math.hypot(merged[-1][0] - lx, merged[-1][1] - ly) - chain * size
        lengths = [math.hypot(b[0] - a[0], b[1] - a[1]) for a, b in zip(merged, merged[1:])]
        dense = [merged[0]]
        marks = []  # (index in dense where a corner starts, its speed limit)
        last = len(merged) - 2  # index of the last segment
        for k in range(1, len(merged) - 1):
            (x0, y0), (x1, y1), (x2, y2) = merged[k - 1], merged[k], merged[k + 1]
            ax, ay = (x1 - x0) / lengths[k - 1], (y1 - y0) / lengths[k - 1]
            bx_, by_ = (x2 - x1) / lengths[k], (y2 - y1) / lengths[k]
            cos_turn = max(-1.0, min(1.0, ax * bx_ + ay * by_))
            theta = math.acos(cos_turn)
            into_push = push is not None and k == last
            arc = None
            if 0.05 < theta < 2.2:
                t_in = lengths[k - 1] * (0.9 if k == 1 else 0.5)
                if into_push:
                    t_out = contact_run - self.push_straight
                else:
                    t_out = lengths[k] * (0.9 if k == last else 0.5)
                half = math.tan(theta / 2.0)
                radius = min(self.max_radius, t_in / half, t_out / half)
                turn = 1.0 if ax * by_ - ay * bx_ > 0 else -1.0
                while radius >= 0.1 * size:
                    arc = _arc((x1, y1), (ax, ay), (bx_, by_), theta, radius, turn)
                    # The pursuit cuts inside fast arcs: their chord must be
                    # clear of the ball too.
                    if (all(_point_clear(to_grid(q), blocked, _MARGIN, peg) for q in arc)
                            and _segment_clear(to_grid(arc[0]), to_grid(arc[-1]), blocked,
                                               BALL_RADIUS / size, peg=peg_touch)):
                        break
                    arc = None
                    radius *= 0.7
            if arc is not None:
                v = min(math.sqrt(self.lateral_accel * radius), self.max_turn_rate * radius)
                marks.append((len(dense), min(v, self.cruise_speed)))
                dense.extend(arc)
            else:
                if cos_turn < -0.3:
                    v = 0.05  # a reversal: stop, then roll the other way
                else:
                    base = self.push_turn_speed if into_push else self.corner_speed
                    v = min(self.cruise_speed, base / math.sqrt(max(1e-9, 1.0 - cos_turn)))
                marks.append((len(dense), v))
                dense.append((x1, y1))
        dense.append(merged[-1])
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
            limits.append((s_last + max(0.0, length - chain * size), self.contact_speed))
        else:
            limits.append((s, 0.0))
        leg.pts = dense
        leg.seg = seg
        leg.limits = limits
        return leg

    # -- act: the controller ----------------------------------------------------------

    def hold(self) -> np.ndarray:
        """Roll and steer off: the ball coasts to a stop."""
        return np.zeros(2)

    def act(self, timestep, scene) -> np.ndarray:
        """The next [roll, steer] action for ``scene`` (the estimate of
        ``timestep``); updates ``status``."""
        task = self._task
        if task is None or not self._legs:
            return np.zeros(2)
        if timestep is not None and timestep.first():
            self._prev_heading = None
        px, py = (float(v) for v in scene.walker_xy)
        vx, vy = (float(v) for v in scene.walker_velocity)
        heading = float(scene.heading)
        prev = self._prev_heading
        rate = 0.0 if prev is None else _wrap(heading - prev) / self._dt
        self._prev_heading = heading
        boxes = np.asarray(scene.box_xy, float).tolist()
        self._steps += 1

        leg = self._legs[self._leg]
        push = leg.push
        # -- where along the leg ---------------------------------------------------
        seg = leg.seg
        n = len(seg)
        i = self._i
        x0, y0, ux, uy, length, s0 = seg[i]
        t = (px - x0) * ux + (py - y0) * uy
        while i + 1 < n:
            tc = min(max(t, 0.0), length)
            d_here = (px - x0 - ux * tc) ** 2 + (py - y0 - uy * tc) ** 2
            x1, y1, u1x, u1y, len1, s1 = seg[i + 1]
            t1 = min(max((px - x1) * u1x + (py - y1) * u1y, 0.0), len1)
            d_next = (px - x1 - u1x * t1) ** 2 + (py - y1 - u1y * t1) ** 2
            if t >= length or d_next < d_here:
                i += 1
                x0, y0, ux, uy, length, s0 = x1, y1, u1x, u1y, len1, s1
                t = (px - x0) * ux + (py - y0) * uy
            else:
                break
        self._i = i
        t = max(t, 0.0) if i > 0 else t
        s_here = s0 + min(t, length)
        speed = math.hypot(vx, vy)
        look = self.look_base + self.look_gain * min(speed, 2.5)
        # The carrot: `look` ahead along the path (beyond its end: straight on).
        s_c = s_here + look
        j = i
        while j + 1 < n and seg[j + 1][5] <= s_c:
            j += 1
        cx0, cy0, cux, cuy, _, cs0 = seg[j]
        along = s_c - cs0
        carrot_x, carrot_y = cx0 + cux * along, cy0 + cuy * along
        if i == j and t < 0.0:  # behind the start: aim at the path's line
            carrot_x, carrot_y = x0 + ux * look, y0 + uy * look

        # -- speed target ----------------------------------------------------------
        v_des = self.cruise_speed
        two_a = 2.0 * self.decel
        for s_k, v_k in leg.limits:
            ahead = s_k - s_here
            if ahead < -0.05:
                continue
            v = math.sqrt(v_k * v_k + two_a * max(ahead, 0.0))
            if v < v_des:
                v_des = v
        rem = 0.0
        progress = leg.total - s_here
        if push is not None:
            index, (dx, dy), (tx, ty), lateral, chain = push
            bx, by = boxes[index]
            rem = (tx - bx) * dx + (ty - by) * dy
            progress += rem
            gap = (bx - px) * dx + (by - py) * dy - CONTACT
            if i == n - 1:
                if gap < 0.02:
                    self._touched = True
                elif not self._touched:
                    # Boxes are light and slide on floor friction: a ball that
                    # meets one off its line or askew drags it sideways. Near
                    # the box, off the line: back off along the line first.
                    ball_off = (py - lateral) if dx else (px - lateral)
                    # A short push (centring a box left short) has no room
                    # to steer the box back onto its line: meet it aligned.
                    tol_align = self.finish_align_tol if chain == 0 else self.align_tol
                    # Each back-off widens the tolerance (no endless shuttling).
                    if gap < self.align_gap and \
                            abs(ball_off) > tol_align * (1 + self._backoffs):
                        if not self._backing:
                            self._backoffs += 1
                        self._backing = True
                    elif gap > self.align_gap + 0.25 or abs(ball_off) < 0.5 * tol_align:
                        self._backing = False
                    if self._backing:
                        back = CONTACT + self.align_gap + 0.35
                        carrot_x, carrot_y = bx - dx * back, by - dy * back
                        if dx:
                            carrot_y = lateral
                        else:
                            carrot_x = lateral
                        v_des = min(v_des, 0.6)
                        self._since_best = 0  # backing off is progress
                if self._touched:
                    if v_des > self.push_speed:
                        v_des = self.push_speed
                    # The ball drags the box sideways (friction 1 on its
                    # face): steer across the push line to bring the box
                    # back onto its cell's centre line before pegs catch it.
                    box_off = ((by if dx else bx) - leg.cell_lat)
                    shift = max(-self.max_recentre, min(self.max_recentre,
                                                        -self.k_recentre * box_off))
                    if dx:
                        carrot_y = leg.cell_lat + shift
                    else:
                        carrot_x = leg.cell_lat + shift
                elif gap > 0.0:
                    v = math.sqrt(self.contact_speed ** 2 + two_a * gap)
                    if v < v_des:
                        v_des = v
            v = math.sqrt(2.0 * self.push_decel * max(rem - self.push_lead, 0.0))
            if v < v_des:
                v_des = v
            off_line = (by - lateral) if dx else (bx - lateral)
        # -- drive direction and heading -------------------------------------------
        want = math.atan2(carrot_y - py, carrot_x - px)
        sign = self._sign
        err = _wrap(want - heading - (0.0 if sign > 0 else _PI))
        if abs(err) > 1.75 or (abs(err) > _PI / 2 and speed < 0.3):
            sign = -sign
            self._sign = sign
            err = _wrap(err + _PI)
        cos_err = math.cos(err)
        floor = self.align_cos
        if cos_err < floor:
            v_des = 0.0
        else:
            v_des *= (cos_err - floor) / (1.0 - floor)
        v_along = sign * (vx * math.cos(heading) + vy * math.sin(heading))
        # Pure pursuit's turn rate (2 v sin(err) / distance) plus a term that
        # turns the head on the spot.
        reach = max(math.hypot(carrot_x - px, carrot_y - py), 0.2)
        w_des = self.k_heading * err + 2.0 * max(v_along, 0.0) * math.sin(err) / reach
        w_max = self.max_yaw_rate
        w_des = max(-w_max, min(w_max, w_des))
        u = (w_des / self.steer_gain + self.steer_deadband * math.tanh(w_des / 0.3)
             + self.k_rate * (w_des - rate))
        steer = -max(-1.0, min(1.0, u))  # a positive steer command turns clockwise
        f = self.k_speed * (v_des - v_along) + self.k_speed_ff * v_des
        if self._touched and push is not None and v_des > 0.0:
            f += self.push_bias
        roll = -sign * max(-1.0, min(1.0, f))  # a negative roll rolls towards the face
        if self.trace is not None:
            self.trace.append((self._steps, self._leg, i, round(px, 2), round(py, 2),
                               round(heading, 2), round(rate, 2), round(err, 2), sign,
                               round(v_des, 2), round(v_along, 2), round(roll, 2),
                               round(steer, 2), round(rem, 3)))
        action = self._action
        action[0] = roll
        action[1] = steer

        # -- status ----------------------------------------------------------------
        if self.status is not Status.RUNNING:
            return action.copy()
        est = scene.abstract_cells
        if est != self._est_seen:
            self._est_seen = est
            est_boxes = frozenset(est[0])
            if est_boxes not in self._expected:
                self._fail(f"estimate deviates: boxes {sorted(est_boxes)} are not on the "
                           f"subgoal's path")
                return action.copy()
            self._est_match = est_boxes == self._goal_boxes and est[1] == self._goal_player
        for k, (bx_, by_) in enumerate(boxes):
            if k in self._pushed_boxes:
                continue
            sx, sy = self._box_start[k]
            if abs(bx_ - sx) > self.disturb_tol or abs(by_ - sy) > self.disturb_tol:
                self._fail(f"box disturbed: box {k} moved "
                           f"{math.hypot(bx_ - sx, by_ - sy):.2f} m but should not have")
                return action.copy()
        box_speed = 0.0
        if push is not None:
            if abs(off_line) > 0.2:
                self._fail(f"box off line: the pushed box left its line by {off_line:.2f} m")
                return action.copy()
            prev_box = self._prev_box
            if prev_box is not None:
                box_speed = math.hypot(bx - prev_box[0], by - prev_box[1]) / self._dt
            self._prev_box = (bx, by)

        last_leg = self._leg == len(self._legs) - 1
        tol = self.center_tol * self._cell
        if push is not None:
            # Settled: the box has (nearly) stopped and the ball no longer pushes it.
            done_leg = rem < tol and box_speed < 0.1 and (gap > 0.03 or v_along < 0.15)
            if done_leg and rem < -0.5 * self._cell:
                self._fail(f"box overshot: by {-rem:.2f} m, out of its cell")
                return action.copy()
        else:
            done_leg = (math.hypot(px - leg.pts[-1][0], py - leg.pts[-1][1]) < 0.25
                        and speed < 0.3)
        if self._est_match:
            if not self._needs_settle or (last_leg and done_leg):
                self.status = Status.SUCCESS
                return action.copy()
        if done_leg and not last_leg:
            self._leg += 1
            cells, push_, blocked, keep = self._legs[self._leg].args
            self._legs[self._leg] = self._make_leg(cells, push_, boxes, blocked, keep=keep,
                                                   start=(px, py))
            self._i = 0
            self._prev_box = None
            self._touched = False
            self._backing = False
            self._backoffs = 0
            self._best = math.inf
            self._since_best = 0
            return action.copy()
        # Stuck: no progress along the trajectory (or of the box) for a while.
        if done_leg:
            self._settle += 1
            if self._settle > self.stuck_steps:
                self._fail("not reached: stopped but the estimate does not match the subgoal")
        elif progress < self._best - 0.02:
            self._best = progress
            self._since_best = 0
        else:
            self._since_best += 1
            if self._since_best > self.stuck_steps:
                what = "the box does not move" if push is not None and i == n - 1 \
                    and gap < 0.05 else "the walker makes no progress"
                self._fail(f"stuck: {what} for {self.stuck_steps} steps")
        return action.copy()


def _walls_and_outside(state) -> frozenset:
    """The state's walls plus a ring of cells just outside its grid."""
    ring = set(state.walls)
    for r in range(-1, state.height + 1):
        ring.add((r, -1))
        ring.add((r, state.width))
    for c in range(-1, state.width + 1):
        ring.add((-1, c))
        ring.add((state.height, c))
    return frozenset(ring)


def _ahead(cell, move):
    dr, dc = DIRECTIONS[move]
    return (cell[0] + dr, cell[1] + dc)


#: Clearance (cells) kept between the ball's centre and blocked cells when
#: cutting corners: the ball's radius plus a margin.
_MARGIN = 0.3


def _arc(vertex, a, b, theta, radius, turn, step=0.1) -> list:
    """Points of the arc of ``radius`` tangent to the lines into and out of ``vertex``."""
    vx, vy = vertex
    t = radius * math.tan(theta / 2.0)
    sx, sy = vx - a[0] * t, vy - a[1] * t
    cx, cy = sx - a[1] * radius * turn, sy + a[0] * radius * turn
    phi = math.atan2(sy - cy, sx - cx)
    n = max(2, int(math.ceil(theta * radius / step)))
    return [(cx + radius * math.cos(phi + turn * theta * i / n),
             cy + radius * math.sin(phi + turn * theta * i / n)) for i in range(n + 1)]


def _point_clear(p, blocked, margin, peg=0.0) -> bool:
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


def _segment_clear(a, b, blocked, margin=_MARGIN, step=0.05, peg=0.0) -> bool:
    length = math.hypot(b[0] - a[0], b[1] - a[1])
    n = max(1, int(length / step) + 1)
    for k in range(n + 1):
        f = k / n
        if not _point_clear((a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f),
                            blocked, margin, peg):
            return False
    return True


def _string_pull(points, blocked, keep=(), peg=0.0) -> list:
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
            if _segment_clear(points[i], points[j], blocked, peg=peg):
                best = j
                j += 1
            else:
                break
        out.append(points[best])
        i = best
    return out
