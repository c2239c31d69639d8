"""`ArmTouchSkill`: touch a board point (or a Go pass area) with the Jaco's fingertips.

The skill plays one move of MuJoXO / MuJoGo (`envs.boards`): the subgoal's
``action`` is an OpenSpiel action id, a board point ``row * N + col`` or, in
Go, the pass action ``N * N`` (touched on the floor-level pass area beside
the board on the hand's side, `_PASS_OFFSET` out from the board's edge).

Geometry (the original's): the arm's base is at (0, 0.4, 0), the board at the
origin; a touch registers where a touch sensor (a 0.7 x half-width square
inside each board square: the target's ``pad_half``) is pressed hardest, in
Go only by a finger geom. The far Go rows are 0.7-0.84 m from the base:
beyond ``lean_start`` (0.7 m) the hand cannot point straight down there, so
the planner *leans* the hand away from the base (fingertips ahead of the
wrist) by about ``lean_rate`` degrees per metre beyond, up to ``max_lean``.

What limits a touch is the arm's joints: the actuators are velocity servos
whose ranges are 0.63 rad/s (shoulder, elbow) and 0.84 rad/s (wrist), and the
wrist servos' small force limits let the wrist accelerate at only ~2.8 rad/s²
(about six control steps from rest to full speed). A Cartesian controller
that asks the wrist to start and stop at will overshoots and oscillates, so
the skill plans postures with mink at `reset` and moves in joint space:

1. **Plan** (`reset`, ~30 ms). Candidate *pre-touch* postures put the closed
   fingertips ``pre_height`` above the target: the hand pointing down, or
   leant outwards for far targets (`_lean`; and rolled by ±12° about its x
   axis, which lifts one side of the fingers), and postures near the current
   one pulled towards that direction with the heading free, which may tilt
   (up to ``max_tilt`` from vertical) where that saves joint travel -- mink
   IK (daqp) from the current posture.
   Candidates whose fingertip footprint would not land inside the target pad
   are dropped; of the rest, the one the joints reach first (trapezoidal
   profiles within each joint's speed and acceleration) is kept, raised if
   the closing fingers would come within ``min_clearance`` of the pads. The
   *touch* posture below it (``press_depth`` under the pad top) moves only
   the fast shoulder and elbow.
2. **Travel** to the pre-touch posture along the straight line in joint
   space: the joint velocities are the line's direction times a speed that
   accelerates and brakes within the joints' limits (the slowest joint at its
   limit, all arriving together). No QP per step (~0.2 ms per `act`).
3. **Descend** along the line to the touch posture once the footprint of the
   fingertips that may touch first -- mesh vertices within ``fast_band`` (or
   ``band``, landing slowed to ``touch_speed``) of the lowest, now and while
   the fingers keep closing -- lies over the target pad with ``safety`` to
   spare. The pad stops the fingers and the touch registers.
4. **Recover**: when the travel brings the fingertips near the pads away
   from the target, or the descent drifts off the pad, or the fingertips
   would not land, the skill lifts with the shoulder and elbow and plans again
   2 cm higher (at most ``max_recoveries`` times).
5. **Touch** (when the touch posture is reached without a move, e.g. the pad
   was already touched): a mink `FrameTask` on the pinch site, solved with
   daqp from the *current* joint angles each step, steers the tool point with
   the wrist damped and the hand pointing as planned: it lifts and presses
   again, up to ``max_presses`` times.

The *tool point* is the centre of the smallest circle around the leading
fingertips' lowest points, at the lowest height; the fingers are closed
throughout (finger velocity at its maximum), so the tips lead. In MuJoXO any
arm geom registers, but every tic-tac-toe square is within ``lean_start``,
so the hand points (nearly) down and only the fingertips come near the board;
in MuJoGo only finger geoms register, and a leant hand still lands on its
leading fingertip(s).

Status: SUCCESS when the agent's next registered move is ``subgoal.action``;
FAILURE (``failure_reason`` starts with the keyword) when another move
registered (``"wrong move"``), the action is not a legal point of the board
(``"illegal"``), no posture reaches the target (``"unreachable"``), the
skill stops progressing (``"no progress"``: ``stall_steps`` steps without
progress or too many recoveries), presses did not register
(``"no registration"``), the skill ran ``max_steps`` steps (``"timeout"``),
the IK failed (``"ik"``) or the episode ended first (``"episode ended"``).
After SUCCESS or FAILURE `act` holds the arm still (fingers closing).

Between `reset` calls the skill keeps only its IK problems (rebuilt when the
environment changes); it never changes the simulation. Attributes for
benchmarks and logs: ``steps`` (of the current subgoal), ``phase``
(``"travel"``, ``"descend"``, ``"touch"``, ``"done"``), ``phase_steps``,
``events`` (phase changes with reasons), ``plan_ms``, ``planned_time``
(seconds the joints need to reach the pre-touch posture), ``touch_tilt``.
"""

from __future__ import annotations

import math
import time

import mink
import mujoco
import numpy as np

from skills.base import Skill, Status

__all__ = ["ArmTouchSkill", "DOWN_QUAT", "JOINT_ACCELERATION"]

#: Pinch site pointing straight down (w, x, y, z), as `envs.boards.task.DOWN_QUAT`.
DOWN_QUAT = np.array([0.0, 0.70710678118, 0.70710678118, 0.0])
#: A known-good arm posture above the board (`envs.boards.task.HOME_ARM_QPOS`).
HOME_ARM_QPOS = np.array([1.24, 3.89, 2.13, 5.79, 1.64, 3.89])
#: Accelerations (rad/s²) the velocity servos reach on the six arm joints,
#: measured from rest with a full-range command (the wrist's force limit of
#: 6.8 N m makes it slow).
JOINT_ACCELERATION = np.array([6.5, 4.8, 5.8, 2.8, 2.8, 2.8])

_TIP_NAMES = ("finger_tip_1", "finger_tip_2", "finger_tip_3")
#: Where the skill touches a pass area (the floor-level zones beside the Go
#: board): this far (m) out from the board's side edge, with this tolerance
#: (m) around it, between these distances (m) from the board's centre line
#: towards the arm.
_PASS_OFFSET = 0.12
_PASS_TOLERANCE = 0.07
_PASS_Y_RANGE = (-0.02, 0.25)


_DOWN = np.array([0.0, 0.0, -1.0])


def _skew(k: np.ndarray) -> np.ndarray:
    return np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])


def _pointing(xmat, direction: np.ndarray = _DOWN, roll: float = 0.0) -> mink.SO3:
    """The orientation nearest the site's (``xmat``) whose z axis -- first
    rolled by ``roll`` radians about the site's x axis -- points along the
    unit vector ``direction`` (default straight down).

    Only the smallest rotation is applied: for ``direction`` down the hand's
    heading (rotation about the vertical) is kept.
    """
    rot = np.asarray(xmat, float).reshape(3, 3)
    z = rot @ np.array([0.0, -math.sin(roll), math.cos(roll)])  # (R Rx(roll)) e_z
    axis = np.cross(z, direction)
    sin, cos = float(np.linalg.norm(axis)), float(z @ direction)
    if sin < 1e-9:
        if cos > 0:
            return mink.SO3.from_matrix(rot)
        perpendicular = np.cross(z, [1.0, 0.0, 0.0] if abs(z[0]) < 0.9 else [0.0, 1.0, 0.0])
        skew = _skew(perpendicular / np.linalg.norm(perpendicular))
        align = np.eye(3) + 2 * (skew @ skew)  # half a turn
    else:
        skew = _skew(axis / sin)
        align = np.eye(3) + sin * skew + (1 - cos) * (skew @ skew)
    return mink.SO3.from_matrix(align @ rot)


def _lean_direction(out_xy: np.ndarray, lean_degrees: float) -> np.ndarray:
    """Straight down tilted by ``lean_degrees`` towards the horizontal unit
    vector ``out_xy``."""
    lean = math.radians(lean_degrees)
    return np.array([math.sin(lean) * out_xy[0], math.sin(lean) * out_xy[1], -math.cos(lean)])


def _enclosing_circle(points: np.ndarray) -> tuple[np.ndarray, float]:
    """Smallest circle around three 2-D points: (centre, radius)."""
    a, b, c = points
    best = None
    for p, q, r in ((a, b, c), (b, c, a), (c, a, b)):  # a side as the diameter
        centre = 0.5 * (p + q)
        radius = 0.5 * float(np.linalg.norm(p - q))
        if np.linalg.norm(r - centre) <= radius + 1e-12 and (best is None or radius < best[1]):
            best = (centre, radius)
    if best is not None:
        return best
    # Acute triangle: the circumcircle.
    d = 2 * (a[0] * (b[1] - c[1]) + b[0] * (c[1] - a[1]) + c[0] * (a[1] - b[1]))
    if abs(d) < 1e-15:
        centre = points.mean(axis=0)
    else:
        sa, sb, sc = a @ a, b @ b, c @ c
        centre = np.array([sa * (b[1] - c[1]) + sb * (c[1] - a[1]) + sc * (a[1] - b[1]),
                           sa * (c[0] - b[0]) + sb * (a[0] - c[0]) + sc * (b[0] - a[0])]) / d
    return centre, float(np.max(np.linalg.norm(points - centre, axis=1)))


def _trapezoid_time(distance: np.ndarray, speed: np.ndarray, accel: np.ndarray) -> np.ndarray:
    """Least time to move ``distance`` from rest to rest with those limits."""
    distance = np.abs(distance)
    cruise = distance >= speed ** 2 / accel
    return np.where(cruise, distance / speed + speed / accel, 2 * np.sqrt(distance / accel))


class _ArmModel:
    """The per-environment part: mink problems, index arrays, fingertip meshes."""

    def __init__(self, env, *, orientation_cost: float, wrist_damping: float, band: float):
        task = env.task
        self.band = band
        self.model = model = env.physics.model.ptr
        self.data = env.physics.data.ptr
        qpos_ids = np.asarray(task._joint_qpos)  # pylint: disable=protected-access
        dof_ids = np.asarray(task._joint_dof)  # pylint: disable=protected-access
        self.arm_qpos, self.finger_qpos = qpos_ids[:6], qpos_ids[6:]
        self.arm_dof = dof_ids[:6]
        spec = env.action_spec()
        self.low, self.high = np.asarray(spec.minimum, float), np.asarray(spec.maximum, float)
        self.vmax = self.high[:6]
        site_name = task._pinch_name  # pylint: disable=protected-access
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, site_name)
        # Continuous arm joints (no range): differences are taken modulo 2 pi.
        self.wrap = ~model.jnt_limited[model.dof_jntid[self.arm_dof]].astype(bool)
        finger_joints = model.dof_jntid[dof_ids[6:]]
        self.fingers_closed = model.jnt_range[finger_joints, 1].copy()
        self.limits = [mink.ConfigurationLimit(model)]
        # The arm's base (the body of its first joint turns about the vertical).
        first = int(model.dof_jntid[self.arm_dof[0]])
        self.base_body = int(model.jnt_bodyid[first])
        # Per-step differential IK (touch phase): the pinch site's pose, the
        # wrist damped so the fast shoulder and elbow do the correcting.
        self.config = mink.Configuration(model)
        self.frame = mink.FrameTask(site_name, "site", position_cost=1.0,
                                    orientation_cost=orientation_cost)
        cost = np.full(model.nv, 1e-3)
        cost[self.arm_dof[3:]] = wrist_damping
        self.tasks = [self.frame, mink.DampingTask(model, cost)]
        # Posture IK (plan): full orientation, one heading per solve.
        self.goal_config = mink.Configuration(model)
        self.goal_frame = mink.FrameTask(site_name, "site", position_cost=1.0,
                                         orientation_cost=1.0)
        # Posture IK that may tilt the hand: weak pull towards pointing down,
        # heading free, regularised towards the start posture (slow joints
        # weigh more) so the joints have little to travel.
        self.soft_frame = mink.FrameTask(site_name, "site", position_cost=1.0,
                                         orientation_cost=[0.02, 0.02, 0.0])
        cost = np.zeros(model.nv)
        cost[self.arm_dof] = 0.02 / self.vmax
        self.soft_posture = mink.PostureTask(model, cost=cost)
        # Posture IK with the wrist (nearly) locked: the fast shoulder and
        # elbow move the tool, the hand's orientation changes a little.
        self.position_frame = mink.FrameTask(site_name, "site", position_cost=1.0,
                                             orientation_cost=0.0)
        cost = np.full(model.nv, 1e-4)
        cost[self.arm_dof[3:]] = 1.0
        self.wrist_lock = mink.DampingTask(model, cost)
        # Fingertip mesh vertices in their geoms' frames.
        self.tip_geoms, self.tip_verts = [], []
        for g in range(model.ngeom):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            if name.split("/")[-1] in _TIP_NAMES and model.geom_dataid[g] >= 0:
                mesh = model.geom_dataid[g]
                start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
                self.tip_geoms.append(g)
                self.tip_verts.append(model.mesh_vert[start:start + count].astype(float).copy())
        if len(self.tip_geoms) != 3:
            raise ValueError(f"expected the Jaco hand's three fingertip meshes, found "
                             f"{len(self.tip_geoms)}")

    def joint_delta(self, q_from: np.ndarray, q_to: np.ndarray) -> np.ndarray:
        """Arm joint differences ``q_to - q_from`` (6), the short way round."""
        delta = q_to[self.arm_qpos] - q_from[self.arm_qpos]
        delta[self.wrap] = (delta[self.wrap] + np.pi) % (2 * np.pi) - np.pi
        return delta

    def tool(self, data, tips=None) -> tuple[np.ndarray, float]:
        """(tool point, tip spread) of the kinematics in ``data``.

        The *leading* fingertips (unless ``tips`` names them) are those whose
        lowest point is within ``band`` of the lowest one (all three when the
        hand points down; a tilted hand may lead with one or two). The tool
        point is the centre (x, y) of the smallest circle around the leading
        tips' lowest points, at the lowest height; the spread is that circle's
        radius.
        """
        lows = self.tip_lows(data)
        lowest = lows[:, 2].min()
        leading = lows[list(tips if tips is not None else self.leading(lows))]
        if len(leading) == 3:
            centre, spread = _enclosing_circle(leading[:, :2])
        elif len(leading) == 2:
            centre = leading[:, :2].mean(axis=0)
            spread = 0.5 * float(np.linalg.norm(leading[0, :2] - leading[1, :2]))
        else:
            centre, spread = leading[0, :2], 0.0
        return np.array([centre[0], centre[1], lowest]), spread

    def leading(self, lows: np.ndarray) -> tuple:
        """Indices of the leading fingertips, from their lowest points."""
        return tuple(np.flatnonzero(lows[:, 2] <= lows[:, 2].min() + self.band))

    def _solve_tool(self, config, tool_goal, step, iterations, tolerance, done=None):
        """Iterates ``step(error)`` (one IK step moving the tool by ``error``)
        until the tool point is within ``tolerance`` of ``tool_goal`` (and
        ``done()``). The leading fingertips are frozen during the iterations
        (a jump of the tool point between fingertips would make the IK
        oscillate) and re-chosen once if they changed at the solution.
        Returns True on convergence."""
        data = config.data
        tips = self.leading(self.tip_lows(data))
        switches = 0
        for i in range(iterations + 1):
            tool, _ = self.tool(data, tips)
            error = tool_goal - tool
            if np.linalg.norm(error) < tolerance and (done is None or done(i)):
                now = self.leading(self.tip_lows(data))
                if now == tips or switches == 1:
                    return True  # (after a switch: a posture on the boundary)
                tips, switches = now, switches + 1
                continue
            step(error, i)
        return False

    def _tip_heights(self, data) -> list[np.ndarray]:
        """Each fingertip mesh's vertex heights (world z) in ``data``."""
        return [data.geom_xpos[g][2] + verts @ data.geom_xmat[g][6:9]
                for g, verts in zip(self.tip_geoms, self.tip_verts)]

    def _tip_points(self, data, tip: int, index) -> np.ndarray:
        """World coordinates of fingertip ``tip``'s vertices ``index``."""
        g = self.tip_geoms[tip]
        return data.geom_xpos[g] + self.tip_verts[tip][index] @ data.geom_xmat[g].reshape(3, 3).T

    def tip_lows(self, data) -> np.ndarray:
        """(3, 3): each fingertip mesh's lowest point in ``data``."""
        return np.array([self._tip_points(data, i, int(np.argmin(z)))
                         for i, z in enumerate(self._tip_heights(data))])

    def sweep(self, q: np.ndarray, finger_reach: float, band: float, samples: int = 3):
        """The fingertips' footprint while the fingers close from ``q`` by up to
        ``finger_reach`` radians, the arm fixed at ``q``.

        Returns (points (k, 3), lowest height): for every sample, the fingertip
        mesh vertices within ``band`` (m) of the lowest one -- what may touch
        a pad in the control step of the first contact -- stacked; and the
        lowest height of all samples.
        """
        config = self.goal_config
        start = q[self.finger_qpos]
        points, lowest = [], np.inf
        for f in np.linspace(0.0, 1.0, samples):
            probe = q.copy()
            probe[self.finger_qpos] = np.minimum(start + f * finger_reach, self.fingers_closed)
            config.update(probe)
            heights = self._tip_heights(config.data)
            low = min(float(z.min()) for z in heights)
            for tip, z in enumerate(heights):
                index = np.flatnonzero(z <= low + band)
                if len(index):
                    points.append(self._tip_points(config.data, tip, index))
            lowest = min(lowest, low)
        return np.concatenate(points), lowest

    def tool_jacobian_z(self, tool: np.ndarray) -> np.ndarray:
        """d(tool height)/d(arm joint angles) (6), at the IK configuration."""
        jacp = np.zeros((3, self.model.nv))
        mujoco.mj_jac(self.model, self.config.data, jacp, None, tool,
                      int(self.model.site_bodyid[self.site]))
        return jacp[2, self.arm_dof]

    def base_xy(self) -> np.ndarray:
        """World (x, y) of the arm's base."""
        return self.data.xpos[self.base_body][:2].copy()

    def tilt(self, data) -> float:
        """Angle (degrees) between the pinch site's z axis and straight down."""
        return math.degrees(math.acos(float(np.clip(-data.site_xmat[self.site][8], -1, 1))))

    def solve_soft_posture(self, q_start: np.ndarray, tool_goal: np.ndarray,
                           orientation_cost: float, iterations: int, roll: float = 0.0,
                           tolerance: float = 1e-3, direction: np.ndarray = _DOWN):
        """Joint angles (full qpos) putting the closed fingers' tool point at
        ``tool_goal``, near ``q_start``, the hand pulled towards pointing along
        ``direction`` (default down; `_lean_direction` for far targets) with
        weight ``orientation_cost``, its heading free; with a ``roll`` (radians) the hand is
        also held rolled by that much about its x axis, which lifts one side
        of the closed fingers; (qpos, tilt from vertical in degrees) or None.

        The first half of the iterations regularise towards ``q_start``, the
        rest only damp the steps, so the tool converges exactly.
        """
        config, frame, posture = self.goal_config, self.soft_frame, self.soft_posture
        # A roll is held (about the hand's x axis); the other tilt is free-ish.
        roll_cost = 1.0 if roll else orientation_cost
        frame.set_orientation_cost([roll_cost, orientation_cost, 0.0])
        q = q_start.copy()
        q[self.finger_qpos] = self.fingers_closed
        posture.set_target(q)
        config.update(q)
        data = config.data
        half = iterations // 2

        def step(error, i):
            if i == half:
                posture.set_target(config.q)
            frame.set_target(mink.SE3.from_rotation_and_translation(
                _pointing(data.site_xmat[self.site], direction, roll),
                data.site_xpos[self.site] + error))
            velocity = mink.solve_ik(config, [frame, posture], 1.0, "daqp", damping=1e-4,
                                     limits=self.limits)
            config.integrate_inplace(velocity, 1.0)

        if self._solve_tool(config, tool_goal, step, iterations, tolerance,
                            done=lambda i: i > half):
            return config.q.copy(), self.tilt(data)
        return None

    def solve_shoulder_posture(self, q_start: np.ndarray, tool_goal: np.ndarray,
                               iterations: int, tolerance: float = 1e-3):
        """Joint angles (full qpos) putting the tool point at ``tool_goal``
        moving mostly the shoulder and elbow from ``q_start``; or None."""
        config, frame = self.goal_config, self.position_frame
        config.update(q_start)
        data = config.data

        def step(error, i):
            frame.set_target(mink.SE3.from_rotation_and_translation(
                mink.SO3.from_matrix(data.site_xmat[self.site].reshape(3, 3).copy()),
                data.site_xpos[self.site] + error))
            velocity = mink.solve_ik(config, [frame, self.wrist_lock], 1.0, "daqp",
                                     damping=1e-6, limits=self.limits)
            config.integrate_inplace(velocity, 1.0)

        if self._solve_tool(config, tool_goal, step, iterations, tolerance):
            return config.q.copy()
        return None

    def solve_posture(self, q_start: np.ndarray, tool_goal: np.ndarray, heading: mink.SO3,
                      iterations: int, tolerance: float = 1e-3) -> np.ndarray | None:
        """Joint angles (full qpos) putting the closed fingers' tool point at
        ``tool_goal`` with the pinch site at orientation ``heading``; None if
        the IK does not converge. Starts from ``q_start``."""
        config, frame = self.goal_config, self.goal_frame
        q = q_start.copy()
        q[self.finger_qpos] = self.fingers_closed
        config.update(q)
        data = config.data

        def target(error):
            frame.set_target(mink.SE3.from_rotation_and_translation(
                heading, data.site_xpos[self.site] + error))

        def step(error, i):
            target(error)
            velocity = mink.solve_ik(config, [frame], 1.0, "daqp", damping=1e-4,
                                     limits=self.limits)
            config.integrate_inplace(velocity, 1.0)

        def oriented(i):
            target(np.zeros(3))
            return np.linalg.norm(frame.compute_error(config)[3:]) < 10 * tolerance

        if self._solve_tool(config, tool_goal, step, iterations, tolerance, done=oriented):
            return config.q.copy()
        return None


class ArmTouchSkill(Skill):
    """Touches the subgoal's board point (or pass pad) with the closed fingertips.

    See the module docstring for the control. Args:
      pre_height: height (m) of the tool above the pad top in the pre-touch
        posture.
      press_depth: depth (m) below the pad top of the tool in the touch
        posture (and of the touch phase's aim).
      orientations: (heading, roll) pairs in degrees tried for the pre-touch
        posture: the task's down orientation turned by ``heading`` about the
        vertical and tilted by ``roll`` about the hand's x axis (which lowers
        one side of the closed fingers: a smaller footprint).
      tilt_costs, max_tilt: more candidates, (weight, roll) pairs: postures
        near the start, pulled with that weight towards pointing down (or
        leant, see below) rolled by ``roll`` degrees (so they may tilt towards
        the start), at most ``max_tilt`` degrees from vertical (the near
        Go rows, 0.2 m from the base, are reached fastest well tilted).
      lean_start, lean_rate, lean_step, max_lean: targets beyond ``lean_start``
        (m, horizontally from the arm's base) are tried with the hand leant
        away from the base by ``lean_rate`` degrees per metre beyond, and
        ``lean_step`` degrees more (more leans if none lands), at most
        ``max_lean`` (+ ``lean_step`` in the fallback).
      switch_time: the descent starts when the pre-touch posture is this many
        seconds away at full joint speed.
      guard, lookahead: the skill recovers when, travelling, the tool is (or
        at its current velocity will be within ``lookahead`` seconds) closer
        than ``guard`` (m) to the pad tops away from the target; the descent
        recovers when within ``2.5 * guard`` the fingertips would land off the
        pad.
      accel_margin: fraction of `JOINT_ACCELERATION` the travel plans with.
      speed, gain: the touch phase's (and the lift's) largest tool speed
        (m/s), and the touch phase's proportional gain (1/s).
      slope, clearance, cruise: the touch phase's funnel.
      safety: margin (m) kept between the fingertips and the pad's edge.
      max_steps: steps before FAILURE ``"timeout"``.
      stall_steps: steps without progress before FAILURE ``"no progress"``.
      max_presses: presses without a registered move before FAILURE
        ``"no registration"``.
      max_recoveries: re-plans after which the skill fails (``"no progress"``).
      wait_steps: steps the travel may wait at the pre-touch posture for the
        fingertips to be landable before it recovers.
      damping, orientation_cost, wrist_damping: touch-phase IK weights
        (against 1 for the pinch site's position).
      band, fast_band, touch_speed, landing_decel: the fingertip vertices
        within ``fast_band`` (m) of the lowest one may touch pads in the
        control step of the first contact when the descent lands at full
        speed; within ``band`` when it lands at ``touch_speed`` (m/s, the cap
        growing as ``sqrt(touch_speed**2 + 2 * landing_decel * height)``).
        The descent starts only when those vertices lie over the target pad,
        ``safety`` from its edge; it lands fast when it can.
      min_clearance: no fingertip comes closer (m) to the pads at the
        pre-touch posture, whatever the fingers' closing (it is raised).
      finger_reach: how far (rad) the fingers may close during a descent;
        the footprint must stay over the pad over that range.
      ik_iterations: iterations per posture IK.
    """

    name = "arm-touch"

    def __init__(self, *, pre_height: float = 0.025, press_depth: float = 0.012,
                 orientations=((0, 0), (0, 12), (0, -12)),
                 tilt_costs=((0.02, 0), (0.01, 12), (0.01, -12)),
                 max_tilt: float = 55.0, max_lean: float = 55.0, lean_start: float = 0.7,
                 lean_rate: float = 250.0, lean_step: float = 8.0, switch_time: float = 0.1,
                 guard: float = 0.008, lookahead: float = 0.05, accel_margin: float = 0.85,
                 speed: float = 0.3, gain: float = 5.0, slope: float = 1.6,
                 clearance: float = 0.008,
                 cruise: float = 0.04, safety: float = 0.003, max_steps: int = 60,
                 stall_steps: int = 12, max_presses: int = 3, max_recoveries: int = 2,
                 damping: float = 1e-3, orientation_cost: float = 0.1, wrist_damping: float = 0.05,
                 band: float = 0.006, fast_band: float = 0.015, touch_speed: float = 0.1,
                 landing_decel: float = 1.5, min_clearance: float = 0.012,
                 finger_reach: float = 0.4, wait_steps: int = 12, ik_iterations: int = 12):
        super().__init__()
        self.pre_height, self.press_depth = float(pre_height), float(press_depth)
        self.orientations = tuple((float(h), float(r)) for h, r in orientations)
        self.touch_speed, self.landing_decel = float(touch_speed), float(landing_decel)
        self.tilt_costs = tuple((float(c), float(r)) for c, r in tilt_costs)
        self.max_tilt = float(max_tilt)
        self.lean_start, self.lean_rate = float(lean_start), float(lean_rate)
        self.lean_step, self.max_lean = float(lean_step), float(max_lean)
        self.touch_tilt = math.nan
        self.switch_time, self.guard = float(switch_time), float(guard)
        self.lookahead = float(lookahead)
        self.accel = JOINT_ACCELERATION * float(accel_margin)
        self.speed, self.gain, self.slope = float(speed), float(gain), float(slope)
        self.clearance, self.cruise = float(clearance), float(cruise)
        self.safety = float(safety)
        self.max_steps, self.stall_steps = int(max_steps), int(stall_steps)
        self.max_presses = int(max_presses)
        self.damping = float(damping)
        self.ik_iterations = int(ik_iterations)
        self.min_clearance, self.finger_reach = float(min_clearance), float(finger_reach)
        self.band, self.fast_band = float(band), float(fast_band)
        self._landing_kind = None
        self.max_recoveries = int(max_recoveries)
        self.wait_steps = int(wait_steps)
        self._costs = {"orientation_cost": float(orientation_cost),
                       "wrist_damping": float(wrist_damping), "band": float(band)}
        self._arm: _ArmModel | None = None
        self._env = None
        self._down = mink.SO3(DOWN_QUAT)
        self.subgoal = None
        self.target: np.ndarray | None = None
        self.phase = "done"
        self.phase_steps: dict[str, int] = {}
        self.steps = 0
        self.plan_ms = 0.0

    # -- Skill API ------------------------------------------------------------

    def reset(self, env, subgoal, state) -> None:
        if self._env is not env or self._arm is None:
            self._arm = _ArmModel(env, **self._costs)
            self._env = env
        arm, task = self._arm, env.task
        self.subgoal = subgoal
        self.status = Status.RUNNING
        self.failure_reason = None
        self.steps = 0
        self.phase_steps = {"travel": 0, "descend": 0, "touch": 0}
        self._dt = float(env.control_timestep)
        self._registered = task.moves_registered
        self._moves_before = len(task.moves)
        self._presses = 0
        self._pressing = 0
        self._lifting = False
        self._postures = None
        self._extra_height, self._recoveries, self._recovering = 0.0, 0, False
        self._waits = 0
        self._landing_kind = None
        self._touch_direction = _DOWN
        self._last_tool, self._tool_speed = None, np.zeros(3)
        self.plan_ms = 0.0
        self.planned_time = math.nan
        self.events: list[str] = []
        self._set_phase("travel")
        q = arm.data.qpos.copy()
        arm.config.update(q)
        tool, _ = arm.tool(arm.config.data)
        action = int(subgoal.action)
        game = task.game
        if game.pass_action is not None and action == game.pass_action:
            self._pad_top = self._pass_point(task, tool)
            self._tolerance = _PASS_TOLERANCE
        elif 0 <= action < game.num_points:
            self._pad_top = np.asarray(task.point_position(action), float)
            self._tolerance = float(task.arena.pad_half)
        else:
            self._pad_top, self.target = None, None
            self._fail(f"illegal: action {action} is not a point of this board")
            return
        self.target = self._pad_top - np.array([0.0, 0.0, self.press_depth])
        legal = state.legal_actions() if state is not None and not state.is_terminal() else []
        if action not in legal:
            self._fail(f"illegal: action {action} is not legal in the planned-from state")
            return
        start = time.perf_counter()
        self._postures = self._plan(q)
        self.plan_ms = (time.perf_counter() - start) * 1e3
        if self._postures is None:
            self._fail(f"unreachable: no arm posture puts the fingertips on "
                       f"{np.round(self._pad_top, 3).tolist()}")

    def act(self, timestep) -> np.ndarray:
        arm = self._arm
        if arm is None:
            raise RuntimeError("ArmTouchSkill.act called before reset")
        if self.status is Status.RUNNING:
            self._check_outcome(self._env.task, timestep)
        if self.status is Status.RUNNING and self.steps >= self.max_steps:
            self._fail(f"timeout: no move registered in {self.max_steps} steps")
        if self.status is not Status.RUNNING:
            self.phase = "done"
            return self._hold()
        self.steps += 1
        q = arm.data.qpos.copy()
        arm.config.update(q)
        tool, spread = arm.tool(arm.config.data)
        if self._last_tool is not None:
            self._tool_speed = (tool - self._last_tool) / self._dt
        self._last_tool = tool
        command = None
        if self.phase == "travel":
            command = self._travel(q, tool, spread)
        if command is None and self.phase == "descend":
            command = self._descend(q, tool, spread)
        if command is None and self.status is Status.RUNNING:
            self._set_phase("touch")
            command = self._touch(tool, spread)
        if self.status is not Status.RUNNING:
            self.phase = "done"
            return self._hold()
        self.phase_steps[self.phase] += 1
        return command

    # -- plan, travel, descend ------------------------------------------------

    def _plan(self, q: np.ndarray):
        """(pre-touch, touch) postures, the pre-touch one reached first; or None.

        Candidates: the hand at each of ``orientations`` and tilted postures
        near ``q`` (``tilt_costs``, at most ``max_tilt``); if none is landable,
        a wider set of orientations. The landable ones are tried fastest first
        until one has a touch posture.
        """
        arm = self._arm
        pre_goal = self._pad_top + np.array([0.0, 0.0, self.pre_height + self._extra_height])
        lean = self._lean(pre_goal)
        orientations = [(h, r, t) for t in lean for h, r in self.orientations]
        landable = self._landable(
            self._candidates(q, pre_goal, orientations, self.tilt_costs))
        if not landable:  # a hard case: more orientations, leans and iterations
            leans = sorted({*lean, lean[-1] + self.lean_step, max(lean[0] - self.lean_step, 0.0)})
            landable = self._landable(self._candidates(
                q, pre_goal, [(h, r, t) for t in leans for h in range(-180, 180, 30)
                              for r in (-15, 0, 15)], (),
                iterations=4 * self.ik_iterations))
        timed = sorted(((float(np.max(_trapezoid_time(arm.joint_delta(q, q_pre), arm.vmax,
                                                      self.accel))), index, q_pre)
                        for index, q_pre in enumerate(landable)), key=lambda t: t[:2])
        for duration, _, best in timed:
            # The fingers close on the way (slowly) and half-closed fingertips
            # reach lower than closed ones: raise the pre-touch posture until
            # no fingertip comes within min_clearance of the pads meanwhile.
            probe = best.copy()
            probe[arm.finger_qpos] = q[arm.finger_qpos]
            reach = float(np.max(arm.fingers_closed - q[arm.finger_qpos]))
            _, lowest = arm.sweep(probe, reach, 0.0, 5)
            deficit = self._pad_top[2] + self.min_clearance - lowest
            if deficit > 0:
                raised = arm.solve_shoulder_posture(
                    best, pre_goal + np.array([0.0, 0.0, deficit]), self.ik_iterations)
                if raised is not None and self._landable([raised]):
                    best = raised
            # The touch posture: straight below, moving the (fast) shoulder
            # and elbow only; the hand's orientation changes by a degree or two.
            q_touch = arm.solve_shoulder_posture(best, self.target, self.ik_iterations)
            if q_touch is not None:
                self.planned_time = duration
                self.touch_tilt = arm.tilt(arm.goal_config.data)
                # The touch phase keeps the hand pointing as planned.
                self._touch_direction = arm.goal_config.data.site_xmat[arm.site][[2, 5, 8]].copy()
                return best, q_touch
        return None

    def _lean(self, goal: np.ndarray) -> tuple[float, ...]:
        """Outward leans (degrees) to try for a target at ``goal``.

        With the hand pointing down the arm reaches about ``lean_start`` (m,
        horizontally from its base); farther targets need the hand leaning
        away from the base (the fingertips ahead of the wrist), by about
        ``lean_rate`` degrees per metre beyond, up to ``max_lean``. Near
        targets: only 0; far ones: the estimate and ``lean_step`` more.
        """
        reach = float(np.linalg.norm(goal[:2] - self._arm.base_xy()))
        need = self.lean_rate * (reach - self.lean_start)
        if need <= 0:
            return (0.0,)
        need = min(need, self.max_lean - self.lean_step)
        return (need, need + self.lean_step)

    def _rotation(self, goal: np.ndarray, heading: float, roll: float,
                  lean: float) -> mink.SO3:
        """The down orientation turned by ``heading`` about the vertical,
        rolled by ``roll`` about the hand's x axis, and leant by ``lean``
        (degrees) away from the arm's base (the hand's z axis tilted from
        straight down towards the horizontal direction base -> ``goal``)."""
        rotation = (mink.SO3.from_z_radians(math.radians(heading)) @ self._down
                    @ mink.SO3.from_x_radians(math.radians(roll)))
        if lean:
            out = goal[:2] - self._arm.base_xy()
            out /= max(float(np.linalg.norm(out)), 1e-9)
            axis = np.array([out[1], -out[0], 0.0])  # turns -z towards `out`
            rotation = mink.SO3.exp(axis * math.radians(lean)) @ rotation
        return rotation

    def _candidates(self, q, goal, orientations, tilt_costs, iterations=None) -> list:
        """Pre-touch postures: at ``orientations`` ((heading, roll, lean)
        triples, `_rotation`), and tilted near ``q``."""
        arm = self._arm
        iterations = iterations or self.ik_iterations
        found = []
        for heading, roll, lean in orientations:
            rotation = self._rotation(goal, heading, roll, lean)
            q_pre = arm.solve_posture(q, goal, rotation, iterations)
            if q_pre is not None:
                found.append(q_pre)
        leans = sorted({lean for _, _, lean in orientations})
        out = goal[:2] - arm.base_xy()
        out /= max(float(np.linalg.norm(out)), 1e-9)
        for lean in leans:
            direction = _lean_direction(out, lean)
            for cost, roll in tilt_costs:
                solved = arm.solve_soft_posture(q, goal, cost, 2 * iterations, math.radians(roll),
                                                direction=direction)
                if solved is not None and solved[1] <= self.max_tilt:
                    found.append(solved[0])
        return found

    def _landable(self, postures: list) -> list:
        """The postures whose closed fingertips' footprint (slow landing) lies
        over the pad."""
        return [q for q in postures
                if self._footprint_offset(q, 0.0, self.band) + self.safety <= self._tolerance]

    def _footprint_offset(self, q: np.ndarray, finger_reach: float, band: float) -> float:
        """Largest distance along x or y (the pads are squares) from the target
        of the fingertips' footprint (``band``) at ``q`` while the fingers
        close by up to ``finger_reach``."""
        points, _ = self._arm.sweep(q, finger_reach, band, 3 if finger_reach > 0 else 1)
        return float(np.max(np.abs(points[:, :2] - self._pad_top[:2])))

    def _line_command(self, q: np.ndarray, goal: np.ndarray, brake: bool):
        """Joint-velocity command along the straight line in joint space to ``goal``.

        The slowest joint runs at its limit and the others in step. With
        ``brake`` (travel) the speed along the line also ramps up and brakes
        within every joint's acceleration (`JOINT_ACCELERATION` times
        ``accel_margin``), so the posture is reached without overshoot;
        without it (the short descent) it is full speed at once.

        Returns (command, seconds to ``goal`` at full speed).
        """
        arm = self._arm
        delta = arm.joint_delta(q, goal)
        scaled = np.abs(delta) / arm.vmax
        remaining = float(np.max(scaled))  # seconds at full speed
        command = np.zeros(arm.low.shape)
        command[6:] = arm.high[6:]  # close the fingers
        if remaining < 1e-6:
            return command, remaining
        speed = 1.0  # fraction of full speed along the line
        if brake:
            moving = np.abs(delta) > 1e-9
            # Acceleration along the line (fraction of full speed per second).
            accel = float(np.min(self.accel[moving] * remaining / np.abs(delta[moving])))
            slowest = int(np.argmax(scaled))
            current = float(np.clip(arm.data.qvel[arm.arm_dof[slowest]] * np.sign(delta[slowest])
                                    / arm.vmax[slowest], 0.0, 1.0))
            half = 0.5 * accel * self._dt  # braking a step late
            speed = min(1.0, current + accel * self._dt,
                        math.sqrt(2 * accel * remaining + half * half) - half)
        command[:6] = delta / remaining * speed
        return np.clip(command, arm.low, arm.high), remaining

    def _travel(self, q: np.ndarray, tool: np.ndarray, spread: float):
        """To the pre-touch posture; None when the descent (or touch) should start.

        The descent starts once the pre-touch posture is within
        ``switch_time`` (at full joint speed) *and* every fingertip is over the
        pad with ``safety`` to spare (so the closing fingers are waited for).
        """
        dxy = float(np.linalg.norm(tool[:2] - self._pad_top[:2]))
        height = tool[2] - self._pad_top[2]
        off_target = dxy > self._tolerance
        # The travel ends pre_height above the pads, braking; below that height
        # the tool's current velocity is extrapolated `lookahead` seconds.
        ahead = height + min(self._tool_speed[2], 0.0) * self.lookahead
        if off_target and (height < self.guard
                           or (height < self.pre_height and ahead < self.guard)):
            if self._recovering:
                return self._lift_command(tool)  # still climbing after a re-plan
            return self._recover(q, tool, "near the board off target")
        self._recovering = False
        command, remaining = self._line_command(q, self._postures[0], brake=True)
        if remaining <= self.switch_time:
            self._landing_kind = self._landing(q)
            if self._landing_kind is not None:
                self._set_phase("descend")
                return None
            # Waiting for the closing fingers; if they are closed (or take too
            # long) and still would not land on the pad, plan again.
            self._waits += 1
            closed = np.all(q[self._arm.finger_qpos] >= self._arm.fingers_closed - 0.05)
            if self._waits > self.wait_steps or (closed and remaining < 0.02):
                self._waits = 0
                return self._recover(q, tool, "the fingertips would not land on the pad")
        # Progress: the posture coming nearer or the fingers closing.
        if self._progress(remaining + spread, threshold=0.004):
            return None
        return command

    def _recover(self, q: np.ndarray, tool: np.ndarray, why: str) -> np.ndarray | None:
        """Climbs, and plans the travel again from ``q`` with a higher
        pre-touch posture; returns this step's (lift) command, or None after
        FAILURE."""
        self._recoveries += 1
        if self._recoveries > self.max_recoveries:
            self._fail(f"no progress: {why} {self._recoveries} times")
            return None
        self._extra_height += 0.02
        postures = self._plan(q)
        if postures is None:
            self._fail(f"unreachable: no posture above the target from here ({why})")
            return None
        self._postures = postures
        self._set_phase("travel", why)
        self._recovering = True
        return self._lift_command(tool)

    def _lift_command(self, tool: np.ndarray) -> np.ndarray:
        """Raises the tool at ``speed`` with the shoulder and elbow."""
        arm = self._arm
        command = self._hold()
        big = np.array([1, 2])  # shoulder, elbow (the base turns about the vertical)
        jz = arm.tool_jacobian_z(tool)[big]
        norm = float(jz @ jz)
        if norm > 1e-9:
            qdot = jz * (self.speed / norm)
            qdot /= max(1.0, float(np.max(np.abs(qdot) / arm.vmax[big])))
            command[big] = qdot
        return command

    def _landing(self, q: np.ndarray, margin: float | None = None) -> str | None:
        """How the fingertips may land from ``q``: ``"fast"`` when their
        footprint with ``fast_band`` lies over the target pad with ``margin``
        (default ``safety``) to spare, now and while the fingers close by up to
        ``finger_reach`` radians; else ``"slow"`` (at ``touch_speed``) when the
        footprint with ``band`` does; else None."""
        margin = self.safety if margin is None else margin
        for kind, band in (("fast", self.fast_band), ("slow", self.band)):
            if self._footprint_offset(q, self.finger_reach, band) + margin <= self._tolerance:
                return kind
        return None

    def _descend(self, q: np.ndarray, tool: np.ndarray, spread: float):
        """Down to the touch posture; None when the touch phase should take over."""
        height = tool[2] - self._pad_top[2]
        dxy = float(np.linalg.norm(tool[:2] - self._pad_top[:2]))
        if 0.0 < height < 2.5 * self.guard and self._landing(q, margin=0.0) is None:
            # A fingertip would land off the pad: climb and plan again.
            return self._recover(q, tool, "drifting off the pad")
        command, remaining = self._line_command(q, self._postures[1], brake=False)
        if remaining < 0.01:
            self._set_phase("touch", "touch posture reached without a move")
            return None
        if self._landing_kind == "slow":
            # Land at touch_speed: braking from the descent's speed takes the
            # big joints about a step, so the cap grows with the height.
            cap = math.sqrt(self.touch_speed ** 2 + 2 * self.landing_decel * max(height, 0.0))
            down = -float(self._arm.tool_jacobian_z(tool) @ command[:6])
            if down > cap:
                command[:6] *= cap / down
        if self._progress(remaining, threshold=0.005):
            return None
        return command

    # -- touch (Cartesian) ------------------------------------------------------

    def _touch(self, tool: np.ndarray, spread: float) -> np.ndarray:
        arm = self._arm
        velocity = self._tool_velocity(tool, spread)
        if self.status is not Status.RUNNING:
            return self._hold()
        # Tilt corrected, heading kept. The pinch site's target is where it must
        # be for the tool point (fixed in the hand's frame while the fingers are
        # closed) to move by velocity * dt at the target rotation.
        data = arm.config.data
        xmat = data.site_xmat[arm.site].reshape(3, 3)
        rotation = _pointing(xmat, self._touch_direction)
        offset = xmat.T @ (tool - data.site_xpos[arm.site])
        pinch = tool + velocity * self._dt - rotation.as_matrix() @ offset
        arm.frame.set_target(mink.SE3.from_rotation_and_translation(rotation, pinch))
        try:
            qdot = mink.solve_ik(arm.config, arm.tasks, self._dt, "daqp",
                                 damping=self.damping, limits=arm.limits)
        except Exception as error:  # noqa: BLE001 - mink raises several kinds
            self._fail(f"ik: {type(error).__name__}: {error}")
            return self._hold()
        command = np.zeros(arm.low.shape)
        command[:6] = qdot[arm.arm_dof]
        ratio = float(np.max(np.abs(command[:6]) / arm.vmax))
        if ratio > 1.0:
            command[:6] /= ratio
        command[6:] = arm.high[6:]
        return np.clip(command, arm.low, arm.high)

    def _tool_velocity(self, tool: np.ndarray, spread: float) -> np.ndarray:
        """The tool's desired velocity (m/s) in the touch phase."""
        goal, top = self.target, self._pad_top[2]
        horizontal = goal[:2] - tool[:2]
        dxy = float(np.linalg.norm(horizontal))
        height = tool[2] - top
        if self._progress(float(np.linalg.norm(goal - tool)), threshold=0.002):
            return np.zeros(3)
        at_board = height < 0.002 and dxy < self._tolerance
        self._pressing = self._pressing + 1 if at_board else 0
        if self._pressing > 3:
            # Pressed for a few steps without registering (e.g. the pad was
            # already touched when the skill started): lift and press again.
            self._presses += 1
            if self._presses >= self.max_presses:
                self._fail(f"no registration: pressed {self._presses} times without a move")
                return np.zeros(3)
            self._lifting = True
            self._pressing = 0
        if self._lifting:
            if height > 0.02:
                self._lifting = False
                self._progress(np.inf, reset=True)
            else:
                return np.array([0.0, 0.0, self.speed])
        # Horizontal: straight for the target, proportional near it.
        v_xy = (horizontal * (min(self.speed, self.gain * dxy) / dxy) if dxy > 1e-9
                else np.zeros(2))
        # Vertical: into the pad once every fingertip would land on it, else
        # down (or up) to the funnel's height at this distance.
        capture = float(np.clip(self._tolerance - spread - self.safety, 0.0, 0.02))
        if dxy <= capture:
            allowed = -self.press_depth
        else:
            allowed = self.clearance + min(self.slope * (dxy - capture), self.cruise)
            if height < allowed - 0.003:
                v_xy = np.zeros(2)  # below the funnel: climb back first
        v_z = float(np.clip(self.gain * (allowed - height), -self.speed, self.speed))
        return np.array([v_xy[0], v_xy[1], v_z])

    # -- bookkeeping -----------------------------------------------------------

    def _set_phase(self, phase: str, why: str = "") -> None:
        if phase != self.phase and why:
            self.events.append(f"{self.steps}: {self.phase} -> {phase} ({why})")
        self.phase = phase
        self._progress(np.inf, reset=True)

    def _progress(self, measure: float, *, threshold: float = 0.0, reset: bool = False) -> bool:
        """Tracks the best ``measure`` of the phase; True (and FAILURE) after a stall."""
        if reset:
            self._best, self._best_step = measure, self.steps
            return False
        if measure < self._best - threshold:
            self._best, self._best_step = measure, self.steps
        elif self.steps - self._best_step >= self.stall_steps:
            self._fail(f"no progress for {self.stall_steps} steps in the {self.phase} phase")
            return True
        return False

    @staticmethod
    def _pass_point(task, tool: np.ndarray) -> np.ndarray:
        """The point of the pass area on the tool's side of the board to touch:
        `_PASS_OFFSET` beside the board's edge (well clear of its squares),
        level with the tool within `_PASS_Y_RANGE` (where the arm reaches it
        with the hand pointing down), at the pass geom's top."""
        arena = task.arena
        cx, cy = arena.centre
        side = "left" if tool[0] < cx else "right"
        point = np.array(task.pass_position(side), float)
        point[0] = cx + math.copysign(arena.half_board + _PASS_OFFSET, point[0] - cx)
        point[1] = np.clip(tool[1], cy + _PASS_Y_RANGE[0], cy + _PASS_Y_RANGE[1])
        return point

    def _check_outcome(self, task, timestep) -> None:
        if task.moves_registered > self._registered:
            moves = task.moves
            played = moves[self._moves_before] if len(moves) > self._moves_before else None
            if played == int(self.subgoal.action):
                self.status = Status.SUCCESS
            else:
                self._fail(f"wrong move: registered {played} instead of "
                           f"{int(self.subgoal.action)}")
        elif timestep is not None and timestep.last():
            self._fail("episode ended before the move registered")

    def _hold(self) -> np.ndarray:
        arm = self._arm
        command = np.zeros(arm.low.shape)
        command[6:] = arm.high[6:]
        return command

    def __repr__(self) -> str:
        return f"ArmTouchSkill(pre_height={self.pre_height:g}, max_tilt={self.max_tilt:g})"
