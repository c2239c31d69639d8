"""Posture planning with mink: the pre-touch and touch postures for a target.

`PostureIK` solves one posture (the tool point at a goal; the hand at a given
orientation, or pulled softly towards one near a start posture, or moved by
the shoulder and elbow only). `PosturePlanner` tries candidate postures,
keeps those whose fingertips would land on the pad, and picks the one the
joints reach first (module docstring of `skills.arm`, step 1).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import mink
import numpy as np

from skills.arm.config import ArmTouchConfig
from skills.arm.geometry import DOWN, DOWN_QUAT, lean_direction, pointing, trapezoid_time
from skills.arm.model import JOINT_ACCELERATION, ArmModel
from skills.arm.targets import TouchTarget


class PostureIK:
    """Posture IK problems on the arm model's ``scratch`` configuration."""

    def __init__(self, arm: ArmModel):
        self.arm = arm
        model, site = arm.model, arm.site_name
        # Full orientation, one heading per solve.
        self.frame = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=1.0)
        # May tilt the hand: weak pull towards pointing down, heading free,
        # regularised towards the start posture (slow joints weigh more) so the
        # joints have little to travel.
        self.soft_frame = mink.FrameTask(
            site, "site", position_cost=1.0, orientation_cost=[0.02, 0.02, 0.0]
        )
        cost = np.zeros(model.nv)
        cost[arm.arm_dof] = 0.02 / arm.vmax
        self.soft_posture = mink.PostureTask(model, cost=cost)
        # The wrist (nearly) locked: the fast shoulder and elbow move the
        # tool, the hand's orientation changes a little.
        self.position_frame = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=0.0)
        cost = np.full(model.nv, 1e-4)
        cost[arm.arm_dof[3:]] = 1.0
        self.wrist_lock = mink.DampingTask(model, cost)

    def _solve_tool(self, config, tool_goal, step, iterations, tolerance, done=None):
        """Iterates ``step(error)`` (one IK step moving the tool by ``error``)
        until the tool point is within ``tolerance`` of ``tool_goal`` (and
        ``done()``). The leading fingertips are frozen during the iterations
        (a jump of the tool point between fingertips would make the IK
        oscillate) and re-chosen once if they changed at the solution.
        Returns True on convergence."""
        arm, data = self.arm, config.data
        tips = arm.leading(arm.tip_lows(data))
        switches = 0
        for i in range(iterations + 1):
            tool, _ = arm.tool(data, tips)
            error = tool_goal - tool
            if np.linalg.norm(error) < tolerance and (done is None or done(i)):
                now = arm.leading(arm.tip_lows(data))
                if now == tips or switches == 1:
                    return True  # (after a switch: a posture on the boundary)
                tips, switches = now, switches + 1
                continue
            step(error, i)
        return False

    def soft(
        self,
        q_start: np.ndarray,
        tool_goal: np.ndarray,
        orientation_cost: float,
        iterations: int,
        roll: float = 0.0,
        tolerance: float = 1e-3,
        direction: np.ndarray = DOWN,
    ):
        """Joint angles (full qpos) putting the closed fingers' tool point at
        ``tool_goal``, near ``q_start``, the hand pulled towards pointing along
        ``direction`` (default down; `lean_direction` for far targets) with
        weight ``orientation_cost``, its heading free; with a ``roll`` (radians)
        the hand is also held rolled by that much about its x axis, which lifts
        one side of the closed fingers; (qpos, tilt from vertical in degrees)
        or None.

        The first half of the iterations regularise towards ``q_start``, the
        rest only damp the steps, so the tool converges exactly.
        """
        arm = self.arm
        config, frame, posture = arm.scratch, self.soft_frame, self.soft_posture
        # A roll is held (about the hand's x axis); the other tilt is free-ish.
        roll_cost = 1.0 if roll else orientation_cost
        frame.set_orientation_cost([roll_cost, orientation_cost, 0.0])
        q = q_start.copy()
        q[arm.finger_qpos] = arm.fingers_closed
        posture.set_target(q)
        config.update(q)
        data = config.data
        half = iterations // 2

        def step(error, i):
            if i == half:
                posture.set_target(config.q)
            frame.set_target(
                mink.SE3.from_rotation_and_translation(
                    pointing(data.site_xmat[arm.site], direction, roll),
                    data.site_xpos[arm.site] + error,
                )
            )
            velocity = mink.solve_ik(
                config, [frame, posture], 1.0, "daqp", damping=1e-4, limits=arm.limits
            )
            config.integrate_inplace(velocity, 1.0)

        if self._solve_tool(
            config, tool_goal, step, iterations, tolerance, done=lambda i: i > half
        ):
            return config.q.copy(), arm.tilt(data)
        return None

    def shoulder(
        self, q_start: np.ndarray, tool_goal: np.ndarray, iterations: int, tolerance: float = 1e-3
    ):
        """Joint angles (full qpos) putting the tool point at ``tool_goal``
        moving mostly the shoulder and elbow from ``q_start``; or None."""
        arm = self.arm
        config, frame = arm.scratch, self.position_frame
        config.update(q_start)
        data = config.data

        def step(error, i):
            frame.set_target(
                mink.SE3.from_rotation_and_translation(
                    mink.SO3.from_matrix(data.site_xmat[arm.site].reshape(3, 3).copy()),
                    data.site_xpos[arm.site] + error,
                )
            )
            velocity = mink.solve_ik(
                config, [frame, self.wrist_lock], 1.0, "daqp", damping=1e-6, limits=arm.limits
            )
            config.integrate_inplace(velocity, 1.0)

        if self._solve_tool(config, tool_goal, step, iterations, tolerance):
            return config.q.copy()
        return None

    def oriented(
        self,
        q_start: np.ndarray,
        tool_goal: np.ndarray,
        rotation: mink.SO3,
        iterations: int,
        tolerance: float = 1e-3,
    ) -> np.ndarray | None:
        """Joint angles (full qpos) putting the closed fingers' tool point at
        ``tool_goal`` with the pinch site at orientation ``rotation``; None if
        the IK does not converge. Starts from ``q_start``."""
        arm = self.arm
        config, frame = arm.scratch, self.frame
        q = q_start.copy()
        q[arm.finger_qpos] = arm.fingers_closed
        config.update(q)
        data = config.data

        def target(error):
            frame.set_target(
                mink.SE3.from_rotation_and_translation(rotation, data.site_xpos[arm.site] + error)
            )

        def step(error, i):
            target(error)
            velocity = mink.solve_ik(config, [frame], 1.0, "daqp", damping=1e-4, limits=arm.limits)
            config.integrate_inplace(velocity, 1.0)

        def done(i):
            target(np.zeros(3))
            return np.linalg.norm(frame.compute_error(config)[3:]) < 10 * tolerance

        if self._solve_tool(config, tool_goal, step, iterations, tolerance, done=done):
            return config.q.copy()
        return None


@dataclass(frozen=True, eq=False)
class TouchPlan:
    """The planned postures (full qpos of the arm model): ``pre`` (the
    fingertips above the target) and ``touch`` (below the pad top); the
    seconds the joints need to reach ``pre`` (``duration``), the hand's tilt
    from vertical at ``touch`` (degrees) and its pointing direction there
    (the pinch site's z axis, for the touch phase)."""

    pre: np.ndarray
    touch: np.ndarray
    duration: float
    tilt: float
    direction: np.ndarray


class PosturePlanner:
    """Plans the pre-touch and touch postures (see `plan`)."""

    def __init__(self, arm: ArmModel, config: ArmTouchConfig):
        self.arm, self.config = arm, config
        self.ik = PostureIK(arm)
        self.accel = joint_acceleration(config)
        self._down = mink.SO3(DOWN_QUAT)

    def plan(self, q: np.ndarray, target: TouchTarget, extra_height: float = 0.0):
        """A `TouchPlan` from the posture ``q`` for ``target``, the pre-touch
        posture ``extra_height`` (m) higher than configured; or None.

        Candidates: the hand at each of ``orientations`` and tilted postures
        near ``q`` (``tilt_costs``, at most ``max_tilt``); if none is landable,
        a wider set of orientations. The landable ones are tried fastest first
        until one has a touch posture.
        """
        arm, cfg = self.arm, self.config
        pad_top = target.pad_top
        press = pad_top - np.array([0.0, 0.0, cfg.press_depth])
        pre_goal = pad_top + np.array([0.0, 0.0, cfg.pre_height + extra_height])
        lean = self.leans(pre_goal)
        orientations = [(h, r, t) for t in lean for h, r in cfg.orientations]
        landable = self.landable(self.candidates(q, pre_goal, orientations, cfg.tilt_costs), target)
        if not landable:  # a hard case: more orientations, leans and iterations
            leans = sorted({*lean, lean[-1] + cfg.lean_step, max(lean[0] - cfg.lean_step, 0.0)})
            landable = self.landable(
                self.candidates(
                    q,
                    pre_goal,
                    [(h, r, t) for t in leans for h in range(-180, 180, 30) for r in (-15, 0, 15)],
                    (),
                    iterations=4 * cfg.ik_iterations,
                ),
                target,
            )
        timed = sorted(
            (
                (
                    float(np.max(trapezoid_time(arm.joint_delta(q, q_pre), arm.vmax, self.accel))),
                    index,
                    q_pre,
                )
                for index, q_pre in enumerate(landable)
            ),
            key=lambda t: t[:2],
        )
        for duration, _, best in timed:
            # The fingers close on the way (slowly) and half-closed fingertips
            # reach lower than closed ones: raise the pre-touch posture until
            # no fingertip comes within min_clearance of the pads meanwhile.
            probe = best.copy()
            probe[arm.finger_qpos] = q[arm.finger_qpos]
            reach = float(np.max(arm.fingers_closed - q[arm.finger_qpos]))
            _, lowest = arm.sweep(probe, reach, 0.0, 5)
            deficit = pad_top[2] + cfg.min_clearance - lowest
            if deficit > 0:
                raised = self.ik.shoulder(
                    best, pre_goal + np.array([0.0, 0.0, deficit]), cfg.ik_iterations
                )
                if raised is not None and self.landable([raised], target):
                    best = raised
            # The touch posture: straight below, moving the (fast) shoulder
            # and elbow only; the hand's orientation changes by a degree or two.
            q_touch = self.ik.shoulder(best, press, cfg.ik_iterations)
            if q_touch is not None:
                data = arm.scratch.data  # at q_touch
                return TouchPlan(
                    pre=best,
                    touch=q_touch,
                    duration=duration,
                    tilt=arm.tilt(data),
                    direction=data.site_xmat[arm.site][[2, 5, 8]].copy(),
                )
        return None

    def leans(self, goal: np.ndarray) -> tuple[float, ...]:
        """Outward leans (degrees) to try for a target at ``goal``.

        With the hand pointing down the arm reaches about ``lean_start`` (m,
        horizontally from its base); farther targets need the hand leaning
        away from the base (the fingertips ahead of the wrist), by about
        ``lean_rate`` degrees per metre beyond, up to ``max_lean``. Near
        targets: only 0; far ones: the estimate and ``lean_step`` more.
        """
        cfg = self.config
        reach = float(np.linalg.norm(goal[:2] - self.arm.base_xy()))
        need = cfg.lean_rate * (reach - cfg.lean_start)
        if need <= 0:
            return (0.0,)
        need = min(need, cfg.max_lean - cfg.lean_step)
        return (need, need + cfg.lean_step)

    def rotation(self, goal: np.ndarray, heading: float, roll: float, lean: float) -> mink.SO3:
        """The down orientation turned by ``heading`` about the vertical,
        rolled by ``roll`` about the hand's x axis, and leant by ``lean``
        (degrees) away from the arm's base (the hand's z axis tilted from
        straight down towards the horizontal direction base -> ``goal``)."""
        rotation = (
            mink.SO3.from_z_radians(math.radians(heading))
            @ self._down
            @ mink.SO3.from_x_radians(math.radians(roll))
        )
        if lean:
            out = goal[:2] - self.arm.base_xy()
            out /= max(float(np.linalg.norm(out)), 1e-9)
            axis = np.array([out[1], -out[0], 0.0])  # turns -z towards `out`
            rotation = mink.SO3.exp(axis * math.radians(lean)) @ rotation
        return rotation

    def candidates(self, q, goal, orientations, tilt_costs, iterations=None) -> list:
        """Pre-touch postures: at ``orientations`` ((heading, roll, lean)
        triples, `rotation`), and tilted near ``q``."""
        cfg = self.config
        iterations = iterations or cfg.ik_iterations
        found = []
        for heading, roll, lean in orientations:
            q_pre = self.ik.oriented(q, goal, self.rotation(goal, heading, roll, lean), iterations)
            if q_pre is not None:
                found.append(q_pre)
        leans = sorted({lean for _, _, lean in orientations})
        out = goal[:2] - self.arm.base_xy()
        out /= max(float(np.linalg.norm(out)), 1e-9)
        for lean in leans:
            direction = lean_direction(out, lean)
            for cost, roll in tilt_costs:
                solved = self.ik.soft(
                    q, goal, cost, 2 * iterations, math.radians(roll), direction=direction
                )
                if solved is not None and solved[1] <= cfg.max_tilt:
                    found.append(solved[0])
        return found

    def landable(self, postures: list, target: TouchTarget) -> list:
        """The postures whose closed fingertips' footprint (slow landing) lies
        over the target's pad."""
        cfg = self.config
        return [
            q
            for q in postures
            if self.arm.footprint_offset(q, target.pad_top, 0.0, cfg.band) + cfg.safety
            <= target.tolerance
        ]


def joint_acceleration(config: ArmTouchConfig) -> np.ndarray:
    """The arm joints' accelerations (rad/s²) the skill plans with."""
    return JOINT_ACCELERATION * config.accel_margin
