"""`ArmTouchSkill`: the controller (plan at reset; travel, descend, recover,
touch; the outcome from the game record). The method is documented in
`skills.arm`."""

from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from skills.arm.config import ArmTouchConfig
from skills.arm.geometry import DOWN
from skills.arm.model import ArmModel
from skills.arm.motion import lift_command, line_command
from skills.arm.postures import PosturePlanner, TouchPlan, joint_acceleration
from skills.arm.targets import touch_target, touch_zones
from skills.arm.touch import TouchIK
from skills.base import Skill, Status

if TYPE_CHECKING:
    from abstract_planners.base import Subgoal

#: Joints of the Jaco and its hand (the action's size before any reset).
_NUM_ACTIONS = 9


def touch_outcome(moves, moves_before: int, action, last: bool) -> tuple[Status, str | None]:
    """A touch's outcome from the game record: (status, failure reason).

    SUCCESS when the first move of ``moves`` after the ``moves_before``
    present when the touch started is ``action``; FAILURE (``"wrong move"``)
    when it is another, or (``"episode ended"``) when the episode ended
    (``last``) first; else RUNNING. Shared by `ArmTouchSkill` and the learned
    arm skill (`skills.learned.arm`).
    """
    action = int(action)
    if len(moves) > moves_before:
        played = moves[moves_before]
        if played == action:
            return Status.SUCCESS, None
        return Status.FAILURE, f"wrong move: registered {played} instead of {action}"
    if last:
        return Status.FAILURE, "episode ended before the move registered"
    return Status.RUNNING, None


class ArmTouchSkill(Skill):
    """Touches the subgoal's board point (or pass area) with the closed fingertips.

    See `skills.arm` for the control and `ArmTouchConfig` for the parameters:
    ``ArmTouchSkill(config)``, ``ArmTouchSkill(pre_height=0.03)`` or both
    (the keywords override the config's fields).

    Observation-only: `reset` takes the board's public description and an
    `ArmScene`; `act` a timestep and the scene estimated from it. The arm's
    kinematic model (``description.arm.model()``) is compiled once per arm
    description and kept between `reset` calls.
    """

    name = "arm-touch"
    # The touch's state, set by `_aim` (which `reset` calls): the plan (None
    # before planning or when unreachable), the landing kind, the tool's last
    # position and the pad's top (None when the zone is not a point).
    _plan: TouchPlan | None
    _landing_kind: str | None
    _last_tool: np.ndarray | None
    _pad_top: np.ndarray | None

    def __init__(self, config: ArmTouchConfig | None = None, **overrides):
        super().__init__()
        config = config if config is not None else ArmTouchConfig()
        self.config = config.replace(**overrides) if overrides else config
        self._accel = joint_acceleration(self.config)
        self._arm: ArmModel | None = None
        self._planner: PosturePlanner | None = None
        self._touch_ik: TouchIK | None = None
        self.subgoal: Subgoal | None = None
        self.target: np.ndarray | None = None
        self.phase = "done"
        self.phase_steps: dict[str, int] = {}
        self.events: list[str] = []
        self.steps = 0
        self.plan_ms = 0.0
        self.planned_time = math.nan
        self.touch_tilt = math.nan

    # -- Skill API ------------------------------------------------------------

    def reset(self, description, subgoal, scene) -> None:
        """Plans the touch of ``subgoal.action`` from ``scene`` (an `ArmScene`)
        in the board of ``description`` (a `BoardDescription`). A move game's
        move is two touches (`touch_zones`): the piece, then, once the scene
        shows it selected, its destination."""
        self._model(description.arm)
        self._description = description
        self.subgoal = subgoal
        self.status = Status.RUNNING
        self.failure_reason = None
        self.steps = 0
        self.phase_steps = {"travel": 0, "descend": 0, "touch": 0}
        self._dt = float(description.control_timestep)
        self._moves_before = len(scene.moves)
        self.plan_ms = 0.0
        self.planned_time = math.nan
        self.events = []
        self._reselects = 0
        action = int(subgoal.action)
        state = scene.state
        legal = state.legal_actions() if state is not None and not state.is_terminal() else []
        zones = touch_zones(description, state, action) if action in legal else None
        self._zones = zones if zones is not None else (action,)
        self._stage = 0
        q = self._aim(scene)
        if q is None:
            return
        if action not in legal:
            self._fail(f"illegal: action {action} is not legal in the planned-from state")
            return
        self._plan_touch(q)

    def _aim(self, scene) -> np.ndarray | None:
        """Starts the touch of zone ``_zones[_stage]``: clears the touch's
        state and sets its target. Returns the arm's posture, or None after
        failing (the zone is not a point of the board)."""
        arm, cfg = self._arm, self.config
        assert arm is not None  # `reset` sets it (`_model`) first
        self._presses = 0
        self._pressing = 0
        self._lifting = False
        self._plan = None
        self._extra_height, self._recoveries, self._recovering = 0.0, 0, False
        self._waits = 0
        self._landing_kind = None
        self._touch_direction = DOWN
        self._last_tool, self._tool_speed = None, np.zeros(3)
        self._set_phase("travel")
        q = arm.set_posture(scene.qpos)
        tool, _ = arm.tool(arm.current.data)
        zone = self._zones[self._stage]
        self._target = touch_target(self._description, zone, tool)
        if self._target is None:
            self._pad_top, self.target = None, None
            self._fail(f"illegal: action {zone} is not a point of this board")
            return None
        self._pad_top, self._tolerance = self._target.pad_top, self._target.tolerance
        self.target = self._pad_top - np.array([0.0, 0.0, cfg.press_depth])
        return q

    def _plan_touch(self, q: np.ndarray) -> None:
        start = time.perf_counter()
        self._plan = self._make_plan(q)
        self.plan_ms += (time.perf_counter() - start) * 1e3
        if self._plan is None:
            assert self._pad_top is not None  # `_aim` set it: it returned a posture
            self._fail(
                f"unreachable: no arm posture puts the fingertips on "
                f"{np.round(self._pad_top, 3).tolist()}"
            )

    def _next_touch(self, scene) -> None:
        """Move games: on to the destination once the piece shows selected;
        back to the piece when its selection was lost (timed out), at most
        ``max_recoveries`` times."""
        if len(self._zones) < 2:
            return
        source = self._zones[0]
        if self._stage == 0 and scene.selected == source:
            self._stage = 1
            self.events.append(f"{self.steps}: selected {source}")
        elif self._stage == 1 and scene.selected != source:
            self._reselects += 1
            if self._reselects > self.config.max_recoveries:
                self._fail(
                    f"no registration: the selection of {source} was lost {self._reselects} times"
                )
                return
            self._stage = 0
            self.events.append(f"{self.steps}: selection of {source} lost")
        else:
            return
        q = self._aim(scene)
        if q is not None:
            self._plan_touch(q)

    def act(self, timestep, scene) -> np.ndarray:
        """The joint-velocity action after ``timestep`` (``scene`` estimated from it)."""
        arm = self._arm
        if arm is None:
            raise RuntimeError("ArmTouchSkill.act called before reset")
        if self.status is Status.RUNNING:
            self._check_outcome(timestep, scene)
        if self.status is Status.RUNNING:
            self._next_touch(scene)
        limit = self.config.max_steps * len(self._zones)  # per touch
        if self.status is Status.RUNNING and self.steps >= limit:
            self._fail(f"timeout: no move registered in {limit} steps")
        if self.status is not Status.RUNNING:
            self.phase = "done"
            return self.hold()
        self.steps += 1
        q = arm.set_posture(scene.qpos)
        self._qvel = arm.arm_velocity(scene.qvel)
        tool, spread = arm.tool(arm.current.data)
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
            return self.hold()
        self.phase_steps[self.phase] += 1
        return command

    def hold(self) -> np.ndarray:
        """Arm joints still, fingers closing (before any reset: all still)."""
        if self._arm is None:
            return np.zeros(_NUM_ACTIONS)
        return self._arm.hold()

    # -- the arm model (per arm description) ----------------------------------

    def _model(self, arm_description) -> ArmModel:
        arm = self._arm
        if arm is None or (
            arm.description is not arm_description and arm.description != arm_description
        ):
            cfg = self.config
            arm = self._arm = ArmModel(arm_description, band=cfg.band)
            self._planner = PosturePlanner(arm, cfg)
            self._touch_ik = TouchIK(
                arm,
                damping=cfg.damping,
                orientation_cost=cfg.orientation_cost,
                wrist_damping=cfg.wrist_damping,
            )
        return arm

    # -- plan, travel, descend ------------------------------------------------

    def _make_plan(self, q: np.ndarray) -> TouchPlan | None:
        # Planning follows a successful `_aim`: the planner (`_model`) and the target are set.
        assert self._planner is not None and self._target is not None
        plan = self._planner.plan(q, self._target, self._extra_height)
        if plan is not None:
            self.planned_time = plan.duration
            self.touch_tilt = plan.tilt
            # The touch phase keeps the hand pointing as planned.
            self._touch_direction = plan.direction
        return plan

    def _line_command(self, q: np.ndarray, goal: np.ndarray, brake: bool):
        assert self._arm is not None  # `act` checked it
        return line_command(self._arm, q, self._qvel, goal, self._accel, self._dt, brake)

    def _travel(self, q: np.ndarray, tool: np.ndarray, spread: float):
        """To the pre-touch posture; None when the descent (or touch) should start.

        The descent starts once the pre-touch posture is within
        ``switch_time`` (at full joint speed) *and* every fingertip is over the
        pad with ``safety`` to spare (so the closing fingers are waited for).
        """
        cfg = self.config
        # Running after a successful `_aim` and plan (`act` checked the arm).
        assert self._arm is not None and self._pad_top is not None and self._plan is not None
        dxy = float(np.linalg.norm(tool[:2] - self._pad_top[:2]))
        height = tool[2] - self._pad_top[2]
        off_target = dxy > self._tolerance
        # The travel ends pre_height above the pads, braking; below that height
        # the tool's current velocity is extrapolated `lookahead` seconds.
        ahead = height + min(self._tool_speed[2], 0.0) * cfg.lookahead
        if off_target and (height < cfg.guard or (height < cfg.pre_height and ahead < cfg.guard)):
            if self._recovering:
                return lift_command(self._arm, tool, cfg.speed)  # still climbing after a re-plan
            return self._recover(q, tool, "near the board off target")
        self._recovering = False
        command, remaining = self._line_command(q, self._plan.pre, brake=True)
        if remaining <= cfg.switch_time:
            self._landing_kind = self._landing(q)
            if self._landing_kind is not None:
                self._set_phase("descend")
                return None
            # Waiting for the closing fingers; if they are closed (or take too
            # long) and still would not land on the pad, plan again.
            self._waits += 1
            closed = np.all(q[self._arm.finger_qpos] >= self._arm.fingers_closed - 0.05)
            if self._waits > cfg.wait_steps or (closed and remaining < 0.02):
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
        if self._recoveries > self.config.max_recoveries:
            self._fail(f"no progress: {why} {self._recoveries} times")
            return None
        self._extra_height += 0.02
        plan = self._make_plan(q)
        if plan is None:
            self._fail(f"unreachable: no posture above the target from here ({why})")
            return None
        self._plan = plan
        self._set_phase("travel", why)
        self._recovering = True
        assert self._arm is not None  # `act` checked it
        return lift_command(self._arm, tool, self.config.speed)

    def _landing(self, q: np.ndarray, margin: float | None = None) -> str | None:
        """How the fingertips may land from ``q``: ``"fast"`` when their
        footprint with ``fast_band`` lies over the target pad with ``margin``
        (default ``safety``) to spare, now and while the fingers close by up to
        ``finger_reach`` radians; else ``"slow"`` (at ``touch_speed``) when the
        footprint with ``band`` does; else None."""
        cfg = self.config
        margin = cfg.safety if margin is None else margin
        assert self._arm is not None and self._pad_top is not None  # as in `_travel`
        for kind, band in (("fast", cfg.fast_band), ("slow", cfg.band)):
            offset = self._arm.footprint_offset(q, self._pad_top, cfg.finger_reach, band)
            if offset + margin <= self._tolerance:
                return kind
        return None

    def _descend(self, q: np.ndarray, tool: np.ndarray, spread: float):
        """Down to the touch posture; None when the touch phase should take over."""
        cfg = self.config
        # Running after a successful `_aim` and plan (`act` checked the arm).
        assert self._arm is not None and self._pad_top is not None and self._plan is not None
        height = tool[2] - self._pad_top[2]
        if 0.0 < height < 2.5 * cfg.guard and self._landing(q, margin=0.0) is None:
            # A fingertip would land off the pad: climb and plan again.
            return self._recover(q, tool, "drifting off the pad")
        command, remaining = self._line_command(q, self._plan.touch, brake=False)
        if remaining < 0.01:
            self._set_phase("touch", "touch posture reached without a move")
            return None
        if self._landing_kind == "slow":
            # Land at touch_speed: braking from the descent's speed takes the
            # big joints about a step, so the cap grows with the height.
            cap = math.sqrt(cfg.touch_speed**2 + 2 * cfg.landing_decel * max(height, 0.0))
            down = -float(self._arm.tool_jacobian_z(tool) @ command[:6])
            if down > cap:
                command[:6] *= cap / down
        if self._progress(remaining, threshold=0.005):
            return None
        return command

    # -- touch (Cartesian) ------------------------------------------------------

    def _touch(self, tool: np.ndarray, spread: float) -> np.ndarray:
        velocity = self._tool_velocity(tool, spread)
        if self.status is not Status.RUNNING:
            return self.hold()
        assert self._touch_ik is not None  # set with the arm (`_model`)
        try:
            return self._touch_ik.command(tool, velocity, self._touch_direction, self._dt)
        except Exception as error:  # noqa: BLE001 - mink raises several kinds
            self._fail(f"ik: {type(error).__name__}: {error}")
            return self.hold()

    def _tool_velocity(self, tool: np.ndarray, spread: float) -> np.ndarray:
        """The tool's desired velocity (m/s) in the touch phase."""
        cfg = self.config
        # Running after a successful `_aim`, which set both.
        assert self.target is not None and self._pad_top is not None
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
            if self._presses >= cfg.max_presses:
                self._fail(f"no registration: pressed {self._presses} times without a move")
                return np.zeros(3)
            self._lifting = True
            self._pressing = 0
        if self._lifting:
            if height > 0.02:
                self._lifting = False
                self._progress(np.inf, reset=True)
            else:
                return np.array([0.0, 0.0, cfg.speed])
        # Horizontal: straight for the target, proportional near it.
        v_xy = horizontal * (min(cfg.speed, cfg.gain * dxy) / dxy) if dxy > 1e-9 else np.zeros(2)
        # Vertical: into the pad once every fingertip would land on it, else
        # down (or up) to the funnel's height at this distance.
        capture = float(np.clip(self._tolerance - spread - cfg.safety, 0.0, 0.02))
        if dxy <= capture:
            allowed = -cfg.press_depth
        else:
            allowed = cfg.clearance + min(cfg.slope * (dxy - capture), cfg.cruise)
            if height < allowed - 0.003:
                v_xy = np.zeros(2)  # below the funnel: climb back first
        v_z = float(np.clip(cfg.gain * (allowed - height), -cfg.speed, cfg.speed))
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
        elif self.steps - self._best_step >= self.config.stall_steps:
            self._fail(f"no progress for {self.config.stall_steps} steps in the {self.phase} phase")
            return True
        return False

    def _check_outcome(self, timestep, scene) -> None:
        """The outcome rule (`touch_outcome`) applied to this timestep."""
        assert self.subgoal is not None  # set by `reset`
        status, reason = touch_outcome(
            scene.moves,
            self._moves_before,
            self.subgoal.action,
            timestep is not None and timestep.last(),
        )
        if status is Status.SUCCESS:
            self.status = Status.SUCCESS
        elif status is Status.FAILURE:
            assert reason is not None  # `touch_outcome` gives a FAILURE its reason
            self._fail(reason)

    def __repr__(self) -> str:
        return (
            f"ArmTouchSkill(pre_height={self.config.pre_height:g}, "
            f"max_tilt={self.config.max_tilt:g})"
        )
