"""`ArmTouchSkill`: touch a board point (or a Go pass area) with the Jaco's fingertips.

The skill plays one move of MuJoXO / MuJoGo (`envs.boards`): the subgoal's
``action`` is an OpenSpiel action id, a board point ``row * N + col`` or, in
Go, the pass action ``N * N`` (touched on the floor-level pass area beside
the board on the hand's side, `PASS_OFFSET` out from the board's edge).

**Observation boundary.** The skill knows what a robot would: the board's
public description (`envs.description.BoardDescription`: the points'
positions, the pads' half-side, the pass zones, the control timestep, and
the arm's own kinematic model, ``description.arm.model()``) and, each step,
an `skills.scene.ArmScene` (the game record and the ``arm/joints_pos`` /
``arm/joints_vel`` observations). It sets the observed joint angles into its
own copy of the arm's model to compute the fingertips' positions; it never
reads the environment's simulation or the task's internals, and never
changes them.

Geometry (the original's): the arm's base is at (0, 0.4, 0), the board at the
origin; a touch registers where a touch sensor (a 0.7 x half-width square
inside each board square: the description's ``pad_half``) is pressed
hardest, in Go only by a finger geom. The far Go rows are 0.7-0.84 m from
the base: beyond ``lean_start`` (0.7 m) the hand cannot point straight down
there, so the planner *leans* the hand away from the base (fingertips ahead
of the wrist) by about ``lean_rate`` degrees per metre beyond, up to
``max_lean``.

What limits a touch is the arm's joints: the actuators are velocity servos
whose ranges are 0.63 rad/s (shoulder, elbow) and 0.84 rad/s (wrist), and the
wrist servos' small force limits let the wrist accelerate at only ~2.8 rad/s²
(about six control steps from rest to full speed; `JOINT_ACCELERATION`). A
Cartesian controller that asks the wrist to start and stop at will overshoots
and oscillates, so the skill plans postures with mink at `reset` and moves in
joint space:

1. **Plan** (`reset`, ~30 ms; `postures`). Candidate *pre-touch* postures put
   the closed fingertips ``pre_height`` above the target: the hand pointing
   down, or leant outwards for far targets (and rolled by ±12° about its x
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
2. **Travel** (`motion`) to the pre-touch posture along the straight line in
   joint space: the joint velocities are the line's direction times a speed
   that accelerates (from the observed joint velocities) and brakes within
   the joints' limits (the slowest joint at its limit, all arriving
   together). No QP per step (~0.2 ms per `act`).
3. **Descend** along the line to the touch posture once the footprint of the
   fingertips that may touch first -- mesh vertices within ``fast_band`` (or
   ``band``, landing slowed to ``touch_speed``) of the lowest, now and while
   the fingers keep closing -- lies over the target pad with ``safety`` to
   spare. The pad stops the fingers and the touch registers.
4. **Recover**: when the travel brings the fingertips near the pads away
   from the target, or the descent drifts off the pad, or the fingertips
   would not land, the skill lifts with the shoulder and elbow and plans again
   2 cm higher (at most ``max_recoveries`` times).
5. **Touch** (`touch`; when the touch posture is reached without a move, e.g.
   the pad was already touched): a mink `FrameTask` on the pinch site, solved
   with daqp from the *current* joint angles each step, steers the tool point
   with the wrist damped and the hand pointing as planned: it lifts and
   presses again, up to ``max_presses`` times.

The *tool point* (`model`) is the centre of the smallest circle around the
leading fingertips' lowest points, at the lowest height; the fingers are
closed throughout (finger velocity at its maximum), so the tips lead. In
MuJoXO any arm geom registers, but every tic-tac-toe square is within
``lean_start``, so the hand points (nearly) down and only the fingertips come
near the board; in MuJoGo only finger geoms register, and a leant hand still
lands on its leading fingertip(s).

Status (from the scene's game record): SUCCESS when the first move recorded
after those present at `reset` is ``subgoal.action``; FAILURE
(``failure_reason`` starts with the keyword) when another move was recorded
(``"wrong move"``), the action is not a legal point of the board
(``"illegal"``), no posture reaches the target (``"unreachable"``), the
skill stops progressing (``"no progress"``: ``stall_steps`` steps without
progress or too many recoveries), presses did not register
(``"no registration"``), the skill ran ``max_steps`` steps (``"timeout"``),
the IK failed (``"ik"``) or the episode ended first (``"episode ended"``).
After SUCCESS or FAILURE `act` holds the arm still (fingers closing), as
does `hold`.

Between `reset` calls the skill keeps only its arm model and IK problems
(rebuilt when the arm's description changes). Attributes for benchmarks and
logs: ``config`` (`ArmTouchConfig`), ``steps`` (of the current subgoal),
``phase`` (``"travel"``, ``"descend"``, ``"touch"``, ``"done"``),
``phase_steps``, ``events`` (phase changes with reasons), ``plan_ms``,
``planned_time`` (seconds the joints need to reach the pre-touch posture),
``touch_tilt``, ``target`` (the point the touch aims at, below the pad top).

Modules: `config` (the parameters), `geometry` (orientations, circles,
travel times), `model` (the arm's own kinematic model and fingertips),
`targets` (where to touch for a move), `postures` (mink posture planning),
`motion` (joint-space commands), `touch` (the touch phase's IK), `skill`
(the controller).
"""

from skills.arm.config import ArmTouchConfig
from skills.arm.geometry import DOWN_QUAT
from skills.arm.model import HOME_ARM_QPOS, JOINT_ACCELERATION, ArmModel
from skills.arm.skill import ArmTouchSkill
from skills.arm.targets import PASS_OFFSET, PASS_TOLERANCE, PASS_Y_RANGE

__all__ = [
    "ArmTouchSkill",
    "ArmTouchConfig",
    "ArmModel",
    "DOWN_QUAT",
    "HOME_ARM_QPOS",
    "JOINT_ACCELERATION",
    "PASS_OFFSET",
    "PASS_TOLERANCE",
    "PASS_Y_RANGE",
]
