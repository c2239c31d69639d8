"""`LearnedArmSkill` (``--skill learned-arm``): MuJoXO / MuJoGo touches by a learned policy.

Given the subgoal (an OpenSpiel action: a board point ``row * N + col`` or,
in Go, the pass), a small MLP (evaluated in numpy) turns the scene estimate
into the arm's joint velocities every control step until the game record
registers a move. Nothing is planned at run time: no IK, no posture search,
no phases -- the policy alone moves the arm. The teacher it was trained
from is the scripted skill `skills.arm.ArmTouchSkill` (mink posture
planning, joint-space travel, descent, recoveries, Cartesian touch), run as
a separate instance on the same timesteps and scenes when labels are asked
for (record-only mode, ``"teacher"`` mode, DAgger), never patched.

Observation boundary
====================

The features come from the subgoal, the `skills.scene.ArmScene` estimate
(``qpos``: the ``arm/joints_pos`` observation; ``moves``, ``state``: the
game record) and the board's public
description (points, pad size, pass zones, the arm's own kinematic model
``description.arm.model()``, in which the observed joint angles are set to
compute the fingertips, as the scripted skill does). Never the simulator.

Where to touch is `skills.arm.targets.touch_target` (the teacher's rule):
the point's pad top with the pad's half-side as tolerance; for the Go pass,
the pass area beside the board on the hand's side at `reset`, tolerance
`PASS_TOLERANCE`. The *target frame* has its origin at that pad top, its
``radial`` axis horizontal from the arm's base towards the target,
``tangential`` = up x radial, and ``up`` vertical.

Features (`FEATURES`, float32, 30 values)
=========================================

======  ====================  =================================================
 0-5    sin_q1 .. sin_q6      sine of the six arm joint angles (rad)
 6-11   cos_q1 .. cos_q6      cosine of them
12-14   finger1 .. finger3    finger angles / the closed angle (0 open, 1 closed)
15-17   tool_r/_t/_u          tool point (the leading fingertips' lowest
                              point, `ArmModel.tool`) minus the target's pad
                              top, target frame, / 0.2 m, clipped to [-3, 3]
18-20   near_r/_t/_u          the same offset, tanh(offset / 0.02 m): fine
                              resolution within a few cm of the pad
21-23   hand_r/_t/_u          the pinch site's z axis (the hand's pointing
                              direction, unit vector), target frame
24      spread                radius of the circle around the leading
                              fingertips' lowest points / 0.02 m, clipped to 3
25      target_range          (horizontal distance arm base -> target - 0.55 m) / 0.2 m
26-27   target_sin/_cos       bearing of the target from the arm's base
                              (angle of the radial axis from world +x)
28      target_height         pad top height (world z) / 0.05 m (board pads
                              0.02 m; the Go pass area is lower)
29      tolerance             the target's tolerance (pad half-side, or the
                              pass area's) / 0.05 m
======  ====================  =================================================

No velocities: the joint velocities (and the tool's) are left out on
purpose: a policy that sees them learns to copy the teacher's smooth current
motion and stalls just above a Go pad (measured: ``results/learned_arm/``).

Action
======

The policy's action is ``ACTION_DIM = 6`` normalised arm joint velocities
in [-1, 1]; `env_action` multiplies them by the joints' speed limits (the
environment's action bounds) and appends the fingers' maximum closing
velocity: the fingers always close, as the teacher keeps them (every
`ArmTouchSkill` command closes them at full speed). ``teacher_action`` is
the teacher's command in the same normalised space (its finger part is
always the maximum), so ``env_action(teacher_action)`` is the teacher's own
command.

Status
======

The scripted skill's outcome rule, `skills.arm.skill.touch_outcome`:
SUCCESS when the first move registered after `reset` is the subgoal's;
FAILURE ``"wrong move"`` when another registers, ``"episode ended"`` when
the episode ends first; and FAILURE ``"timeout"`` after ``max_steps``
control steps (60, the scripted skill's). At `reset`, FAILURE
``"illegal"`` when the action is not a point of the board or not legal in
the planned-from state. The policy never gives up otherwise.

Teacher labels
==============

With labels on (record-only and ``"teacher"`` modes, or ``labels=True``)
the teacher `ArmTouchSkill` is reset with the same subgoal and scene and
shown every timestep; its command (normalised) is ``teacher_action``. When
the student drives, the teacher may give up (its plan stale, no progress,
too many recoveries); it is then reset on the same subgoal from the current
scene (``teacher_resets`` counts them) so it keeps labelling. When it cannot
plan from there, ``teacher_action`` is None for that step.

Checkpoint
==========

``arm_policy.pt`` (next to this file; `skills.learned.policy` format) holds
the network (30 -> 160 -> 160 -> 6, tanh, linear output), the feature names
(checked on load) and ``meta`` (``frames``, ``sim_steps``, the training
command). It is trained by the shared skill trainer on the ``arm`` spec
(`hier_agents.learning.skills.arm`): behaviour cloning of the noisy teacher,
then DAgger rounds in which the student acts at a fraction of the steps
(``python -m hier_agents.learning.train_skill arm ...``; the README and
``results/learned_arm/`` hold the command and the figures).
"""

from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from skills.arm.config import ArmTouchConfig
from skills.arm.model import ArmModel
from skills.arm.skill import ArmTouchSkill, touch_outcome
from skills.arm.targets import TouchTarget, touch_target
from skills.base import Status
from skills.learned.base import LearnedSkill
from skills.learned.policy import load_policy

if TYPE_CHECKING:
    from abstract_planners.base import Subgoal

__all__ = ["LearnedArmSkill", "FEATURES", "ACTION_DIM", "POLICY_PATH", "MAX_STEPS"]

_AXES = ("r", "t", "u")
FEATURES: tuple[str, ...] = (
    tuple(f"sin_q{i}" for i in range(1, 7))
    + tuple(f"cos_q{i}" for i in range(1, 7))
    + tuple(f"finger{i}" for i in range(1, 4))
    + tuple(f"tool_{a}" for a in _AXES)
    + tuple(f"near_{a}" for a in _AXES)
    + tuple(f"hand_{a}" for a in _AXES)
    + ("spread", "target_range", "target_sin", "target_cos", "target_height", "tolerance")
)
ACTION_DIM = 6
#: The shipped checkpoint.
POLICY_PATH = Path(__file__).with_name("arm_policy.pt")
#: Control steps before FAILURE "timeout" (the scripted skill's ``max_steps``).
MAX_STEPS = 60

_POS_SCALE, _NEAR_SCALE = 0.2, 0.02
_RANGE_CENTRE, _RANGE_SCALE = 0.55, 0.2


class LearnedArmSkill(LearnedSkill):
    """Touches the subgoal's board point with a learned joint-velocity policy
    (module docstring). Name ``"learned-arm"``.

    Args:
      policy: a callable features -> normalised joint velocities (6), a
        checkpoint path, ``"teacher"`` (act as the scripted `ArmTouchSkill`),
        or None: the shipped checkpoint (`POLICY_PATH`; `FileNotFoundError`
        when it is missing), or record-only with ``record_only``.
      record_only: ``act`` returns `hold` and only records ``features``,
        ``teacher_action`` and ``status`` (the skill-training environment
        supplies the action).
      labels: run the teacher for ``teacher_action`` (default: in the
        record-only and teacher modes only; True for DAgger).
      max_steps: control steps before FAILURE ``"timeout"``.
      teacher_config: the teacher's `ArmTouchConfig` (default: the default).
    """

    name = "learned-arm"
    FEATURES = FEATURES
    ACTION_DIM = ACTION_DIM
    # The target's frame (radial, tangential, up; rows) and the features that
    # are constant during a touch: set by `reset` once the target is known.
    _frame: np.ndarray
    _target_const: np.ndarray

    def __init__(
        self,
        policy=None,
        *,
        record_only: bool = False,
        labels: bool | None = None,
        max_steps: int = MAX_STEPS,
        teacher_config: ArmTouchConfig | None = None,
    ):
        if record_only:
            policy = None
        elif policy is None or (isinstance(policy, (str, Path)) and policy != "teacher"):
            policy = load_policy(policy if policy is not None else POLICY_PATH, FEATURES)
        super().__init__(policy)
        self.labels = (
            bool(labels) if labels is not None else (policy is None or isinstance(policy, str))
        )
        self.max_steps = int(max_steps)
        self.teacher = ArmTouchSkill(teacher_config)
        self._band = self.teacher.config.band
        self._arm: ArmModel | None = None
        self._features = np.zeros(len(FEATURES), np.float32)
        self._teacher_action: np.ndarray | None = None
        self.subgoal: Subgoal | None = None
        self.target: TouchTarget | None = None
        self.steps = 0
        self.teacher_resets = 0
        self._description = None

    def __repr__(self) -> str:
        kind = (
            "record-only"
            if self.policy is None
            else ("teacher" if isinstance(self.policy, str) else type(self.policy).__name__)
        )
        return f"LearnedArmSkill({kind})"

    # -- Skill API ------------------------------------------------------------

    def reset(self, description, subgoal, scene) -> None:
        arm = self._model(description.arm)
        self._description = description
        self.subgoal = subgoal
        self.status = Status.RUNNING
        self.failure_reason = None
        self.steps = 0
        self.teacher_resets = 0
        self._moves_before = len(scene.moves)
        self._teacher_action = None
        self._features = np.zeros(len(FEATURES), np.float32)
        arm.set_posture(scene.qpos)
        tool, _ = arm.tool(arm.current.data)
        action = int(subgoal.action)
        self.target = touch_target(description, action, tool)
        if self.target is None:
            self._fail(f"illegal: action {action} is not a point of this board")
            return
        # The target frame: radial (base -> target, horizontal), tangential, up.
        pad = np.asarray(self.target.pad_top, float)
        radial = pad[:2] - arm.base_xy()
        distance = float(np.linalg.norm(radial))
        radial = radial / distance if distance > 1e-9 else np.array([1.0, 0.0])
        self._frame = np.array(
            [[radial[0], radial[1], 0.0], [-radial[1], radial[0], 0.0], [0.0, 0.0, 1.0]]
        )
        self._target_const = np.array(
            [
                (distance - _RANGE_CENTRE) / _RANGE_SCALE,
                radial[1],
                radial[0],
                pad[2] / 0.05,
                self.target.tolerance / 0.05,
            ]
        )
        state = scene.state
        legal = state.legal_actions() if state is not None and not state.is_terminal() else []
        if action not in legal:
            self._fail(f"illegal: action {action} is not legal in the planned-from state")
            return
        if self.labels:
            self.teacher.reset(description, subgoal, scene)

    def act(self, timestep, scene) -> np.ndarray:
        if self._arm is None or self.subgoal is None:
            raise RuntimeError("LearnedArmSkill.act called before reset")
        if self.status is Status.RUNNING:
            status, reason = touch_outcome(
                scene.moves,
                self._moves_before,
                self.subgoal.action,
                timestep is not None and timestep.last(),
            )
            if status is Status.SUCCESS:
                self.status = status
            elif status is Status.FAILURE:
                assert reason is not None  # `touch_outcome` gives a FAILURE its reason
                self._fail(reason)
        if self.status is Status.RUNNING and self.steps >= self.max_steps:
            self._fail(f"timeout: no move registered in {self.max_steps} steps")
        if self.status is not Status.RUNNING:
            self._teacher_action = np.zeros(ACTION_DIM, np.float32)
            if self.target is not None:
                self._features = self._compute_features(scene)
            return self.hold()
        self.steps += 1
        self._features = self._compute_features(scene)
        if self.labels:
            self._teacher_action = self._label(timestep, scene)
        if self.policy is None:
            return self.hold()
        if isinstance(self.policy, str):  # "teacher"
            return (
                self.hold()
                if self._teacher_action is None
                else self.env_action(self._teacher_action)
            )
        return self.env_action(self.policy(self._features))

    def hold(self) -> np.ndarray:
        """Arm joints still, fingers closing (before any reset: all still)."""
        if self._arm is None:
            return np.zeros(9)
        return self._arm.hold()

    # -- LearnedSkill ---------------------------------------------------------

    @property
    def features(self) -> np.ndarray:
        """The policy's observation at the last ``act`` (a copy)."""
        return self._features.copy()

    @property
    def teacher_action(self) -> np.ndarray | None:
        """The teacher's normalised joint velocities at the last ``act``
        (None when it could not plan from there; zeros once the touch ended)."""
        return None if self._teacher_action is None else self._teacher_action.copy()

    def env_action(self, policy_action) -> np.ndarray:
        """The environment's 9 joint velocities: the arm's 6 scaled by their
        speed limits, the fingers closing at full speed."""
        if self._arm is None:
            raise RuntimeError("LearnedArmSkill.env_action called before reset")
        command = self._arm.hold()
        command[:6] = (
            np.clip(np.asarray(policy_action, float)[:ACTION_DIM], -1.0, 1.0) * self._arm.vmax
        )
        return np.clip(command, self._arm.low, self._arm.high)

    # -- internals ------------------------------------------------------------

    def _model(self, arm_description) -> ArmModel:
        arm = self._arm
        if arm is None or (
            arm.description is not arm_description and arm.description != arm_description
        ):
            arm = self._arm = ArmModel(arm_description, band=self._band)
        return arm

    def _label(self, timestep, scene) -> np.ndarray | None:
        teacher = self.teacher
        if teacher.status is Status.RUNNING:
            command = teacher.act(timestep, scene)
            if teacher.status is Status.RUNNING:
                return self._normalise(command)
        # The teacher gave up under the student's control (or could not plan
        # last time): plan again on the same subgoal from this scene.
        self.teacher_resets += 1
        teacher.reset(self._description, self.subgoal, scene)
        if teacher.status is not Status.RUNNING:
            return None
        command = teacher.act(timestep, scene)
        return self._normalise(command) if teacher.status is Status.RUNNING else None

    def _normalise(self, command) -> np.ndarray:
        assert self._arm is not None  # `act` checked it
        return np.clip(np.asarray(command, float)[:ACTION_DIM] / self._arm.vmax, -1.0, 1.0).astype(
            np.float32
        )

    def _compute_features(self, scene) -> np.ndarray:
        arm = self._arm
        # `act` checked the arm; a target is set: `act` checks it, or the touch runs.
        assert arm is not None and self.target is not None
        qpos = np.asarray(scene.qpos, float)
        arm.set_posture(qpos)
        data = arm.current.data
        tool, spread = arm.tool(data)
        frame = self._frame
        offset = frame @ (tool - self.target.pad_top)
        hand = frame @ data.site_xmat[arm.site].reshape(3, 3)[:, 2]
        q = qpos[:6]
        out = np.concatenate(
            [
                np.sin(q),
                np.cos(q),
                qpos[6:9] / arm.fingers_closed,
                np.clip(offset / _POS_SCALE, -3.0, 3.0),
                np.tanh(offset / _NEAR_SCALE),
                hand,
                [min(spread / 0.02, 3.0)],
                self._target_const,
            ]
        )
        return out.astype(np.float32)

    @property
    def training_frames(self) -> int:
        meta = getattr(self.policy, "meta", None) or {}
        return int(meta.get("sim_steps", meta.get("frames", 0)))
