"""`BallSkill`: reset builds the legs, act drives them and keeps the status."""

from __future__ import annotations

import math

import numpy as np

from skills.ball import legs
from skills.ball.config import BallConfig
from skills.ball.controller import Contact, Drive, carrot, locate, speed_limit
from skills.base import Skill, Status


class BallSkill(Skill):
    """Closed-loop controller of MuJoBan's rolling ball (see `skills.ball`).

    ``BallSkill(config=None, **overrides)``: ``config`` a `BallConfig`
    (default: the tuned one), ``overrides`` any of its fields
    (``cruise_speed=``, ``stuck_steps=``, ``k_heading=``, ...); unknown
    names raise `TypeError`. The parameters are ``skill.config``; assign a
    new one (``skill.config = skill.config.replace(...)``) to change them.
    """

    name = "ball"

    def __init__(self, config: BallConfig | None = None, *, drive=Drive, **overrides) -> None:
        super().__init__()
        #: Makes the low-level controller (a `skills.ball.controller.Drive`:
        #: carrot and speed target -> [roll, steer]); a learned skill passes
        #: its own (`skills.learned.ball.LearnedDrive`).
        self.make_drive = drive
        if config is None:
            config = BallConfig()
        elif not isinstance(config, BallConfig):
            raise TypeError(f"config must be a BallConfig, got {type(config).__name__}")
        self.config = config.replace(**overrides) if overrides else config
        self._description = None
        self._drive = self.make_drive()
        self._contact = Contact()
        self._legs: list[legs.Leg] = []
        self._action = np.zeros(2)
        #: Set to a list to record per-step controller values (debugging):
        #: (step, leg, segment, x, y, heading, yaw rate, heading error, drive
        #: sign, target speed, speed, roll, steer, box distance to go).
        self.trace = None

    def __repr__(self) -> str:
        c = self.config
        return (
            f"BallSkill(cruise_speed={c.cruise_speed}, push_speed={c.push_speed}, "
            f"stuck_steps={c.stuck_steps})"
        )

    def forget_history(self) -> None:
        """The skill did not see the frames before its next ``reset``: no yaw
        rate from the last heading it saw, the drive direction and the
        back-offs from the start, no leg to carry on."""
        self._drive = self.make_drive()
        self._contact = Contact()
        self._legs, self._leg = [], 0

    # -- reset: the trajectory ------------------------------------------------------

    def reset(self, description, subgoal, scene) -> None:
        """Starts executing ``subgoal`` (planned from ``scene``, a
        `skills.scene.BallScene`) in the task ``description``
        (`envs.description.MujobanDescription`)."""
        contact = self._contact
        # Backing off from a box (see act) goes on across a re-plan that
        # pushes the same box the same way: the option layer may re-plan
        # every few steps, and the ball must not shuttle at the box.
        was_backing = None
        was_backing_now = contact.backing
        backoffs = contact.backoffs
        if self._legs and description is self._description and (contact.backing or backoffs):
            old_push = self._legs[self._leg].push
            was_backing = old_push[:2] if old_push is not None else None
        self.status = Status.RUNNING
        self.failure_reason = None
        if description is not self._description:
            self._description = description
            self._drive = self.make_drive()
        self._cell = float(description.cell_size)
        self._dt = float(description.control_timestep)
        self._legs = []
        self._leg = 0
        self._i = 0
        self._steps = 0
        self._best = math.inf
        self._since_best = 0
        self._settle = 0
        self._est_seen = None
        self._est_match = False
        self._prev_box: tuple[float, float] | None = None  # the pushed box at the last step
        contact.touched = False
        contact.backing = False
        try:
            plan = legs.plan(description, self.config, subgoal, scene)
        except legs.IllegalMove as e:
            self._fail(str(e))
            return
        self._goal_boxes = plan.goal_boxes
        self._goal_player = plan.goal_player
        self._expected = plan.expected
        self._box_start = plan.box_start
        self._needs_settle = plan.needs_settle
        # More of the plan after this subgoal: the next walk is known.
        self._continues = bool(tuple(getattr(subgoal, "plan", None) or ()))
        self._legs = plan.legs
        self._pushed_boxes = plan.pushed_boxes
        contact.backoffs = 0
        if (
            was_backing is not None
            and plan.legs[0].push is not None
            and plan.legs[0].push[:2] == was_backing
        ):
            contact.backing = was_backing_now
            contact.backoffs = backoffs

    # -- act: the controller ----------------------------------------------------------

    def hold(self) -> np.ndarray:
        """Roll and steer off: the ball coasts to a stop."""
        return np.zeros(2)

    def act(self, timestep, scene) -> np.ndarray:
        """The next [roll, steer] action for ``scene`` (the estimate of
        ``timestep``); updates ``status``."""
        if self._description is None or not self._legs:
            return np.zeros(2)
        cfg = self.config
        drive = self._drive
        contact = self._contact
        if timestep is not None and timestep.first():
            drive.prev_heading = None
        px, py = (float(v) for v in scene.walker_xy)
        vx, vy = (float(v) for v in scene.walker_velocity)
        heading = float(scene.heading)
        rate = drive.yaw_rate(heading, self._dt)
        boxes = np.asarray(scene.box_xy, float).tolist()
        self._steps += 1

        leg = self._legs[self._leg]
        seg = leg.seg
        i, t, s_here = locate(seg, self._i, px, py)
        self._i = i
        on_last_segment = i == len(seg) - 1
        speed = math.hypot(vx, vy)
        look = cfg.look_base + cfg.look_gain * min(speed, 2.5)
        carrot_x, carrot_y = carrot(seg, i, t, s_here, look)
        two_a = 2.0 * cfg.decel
        v_des = speed_limit(leg.limits, s_here, cfg.cruise_speed, two_a)
        progress = leg.total - s_here
        box = None
        if leg.push is not None:
            carrot_x, carrot_y, v_des, backing, box = contact.push(
                cfg, leg, on_last_segment, px, py, boxes, (carrot_x, carrot_y), v_des, two_a
            )
            if backing:
                self._since_best = 0  # backing off is progress
            progress += box.rem
        roll, steer, err, v_des, v_along = drive.command(
            cfg,
            px,
            py,
            vx,
            vy,
            heading,
            rate,
            speed,
            carrot_x,
            carrot_y,
            v_des,
            contact.touched and box is not None,
        )
        if self.trace is not None:
            self.trace.append(
                (
                    self._steps,
                    self._leg,
                    i,
                    round(px, 2),
                    round(py, 2),
                    round(heading, 2),
                    round(rate, 2),
                    round(err, 2),
                    drive.sign,
                    round(v_des, 2),
                    round(v_along, 2),
                    round(roll, 2),
                    round(steer, 2),
                    round(box.rem if box is not None else 0.0, 3),
                )
            )
        action = self._action
        action[0] = roll
        action[1] = steer
        if self.status is Status.RUNNING:
            self._update_status(
                scene, boxes, leg, box, px, py, speed, v_along, progress, on_last_segment
            )
        return action.copy()

    # -- status -------------------------------------------------------------------------

    def _fail_if_disturbed(self, boxes) -> bool:
        """Fails (and returns True) if a box this subgoal does not push has
        moved more than ``disturb_tol`` along either axis from its start."""
        tol = self.config.disturb_tol
        for k, (bx_, by_) in enumerate(boxes):
            if k in self._pushed_boxes:
                continue
            sx, sy = self._box_start[k]
            if abs(bx_ - sx) > tol or abs(by_ - sy) > tol:
                self._fail(
                    f"box disturbed: box {k} moved "
                    f"{math.hypot(bx_ - sx, by_ - sy):.2f} m but should not have"
                )
                return True
        return False

    def _start_next_leg(self, boxes, px, py) -> None:
        """Moves on to the next leg, rebuilt from the boxes' and the ball's
        current positions, with fresh progress and contact tracking."""
        self._leg += 1
        self._legs[self._leg] = legs.rebuild(
            self._description, self.config, self._legs[self._leg], boxes, (px, py)
        )
        self._i = 0
        self._prev_box = None
        self._contact.new_leg()
        self._best = math.inf
        self._since_best = 0

    def _update_status(
        self, scene, boxes, leg, box, px, py, speed, v_along, progress, on_last_segment
    ) -> None:
        """Success, failure or the next leg (package docstring, *Status*)."""
        cfg = self.config
        est = scene.abstract_cells
        if est != self._est_seen:
            self._est_seen = est
            est_boxes = frozenset(est[0])
            if est_boxes not in self._expected:
                self._fail(
                    f"estimate deviates: boxes {sorted(est_boxes)} are not on the subgoal's path"
                )
                return
            self._est_match = est_boxes == self._goal_boxes and est[1] == self._goal_player
        if self._fail_if_disturbed(boxes):
            return
        box_speed = 0.0
        if box is not None:
            if abs(box.off_line) > 0.2:
                self._fail(f"box off line: the pushed box left its line by {box.off_line:.2f} m")
                return
            prev_box = self._prev_box
            if prev_box is not None:
                box_speed = math.hypot(box.bx - prev_box[0], box.by - prev_box[1]) / self._dt
            self._prev_box = (box.bx, box.by)

        last_leg = self._leg == len(self._legs) - 1
        tol = cfg.center_tol * self._cell
        if box is not None:
            # Settled: the box has (nearly) stopped and the ball no longer pushes it.
            done_leg = box.rem < tol and box_speed < 0.1 and (box.gap > 0.03 or v_along < 0.15)
            if not done_leg and cfg.chain and box.rem < tol and (self._continues or not last_leg):
                # Chained: the box slides the rest on its own.
                rest = box.rem - box_speed * box_speed / (2.0 * cfg.box_decel)
                done_leg = abs(rest) < 0.5 * tol
            if done_leg and box.rem < -0.5 * self._cell:
                self._fail(f"box overshot: by {-box.rem:.2f} m, out of its cell")
                return
        else:
            done_leg = math.hypot(px - leg.pts[-1][0], py - leg.pts[-1][1]) < 0.25 and speed < 0.3
        if self._est_match:
            if not self._needs_settle or (last_leg and done_leg):
                self.status = Status.SUCCESS
                return
        if done_leg and not last_leg:
            self._start_next_leg(boxes, px, py)
            return
        # Stuck: no progress along the trajectory (or of the box) for a while.
        if done_leg:
            self._settle += 1
            if self._settle > cfg.stuck_steps:
                self._fail("not reached: stopped but the estimate does not match the subgoal")
        elif progress < self._best - 0.02:
            self._best = progress
            self._since_best = 0
        else:
            self._since_best += 1
            if self._since_best > cfg.stuck_steps:
                what = (
                    "the box does not move"
                    if box is not None and on_last_segment and box.gap < 0.05
                    else "the walker makes no progress"
                )
                self._fail(f"stuck: {what} for {cfg.stuck_steps} steps")
