"""Test helper: drive the Jaco arm's fingertips onto a board point with joint commands.

Plain closed-loop control through the environment's own action interface:
the pinch site follows Cartesian waypoints (at most 2 cm per control step,
first at a safe height over the board, then straight down into the pad); the
task's IK turns each waypoint into joint targets and a proportional
joint-velocity command tracks them. Only `env.step` moves the arm.
"""

from __future__ import annotations

import numpy as np

SAFE_HEIGHT = 0.1  # metres above the target while travelling
STEP = 0.02  # metres per control step


def _drive(env, goal, steps, stop=None, gain=8.0):
    task = env.task
    spec = env.action_spec()
    timestep = None
    for _ in range(steps):
        pinch = task.pinch_site_position()
        delta = goal - pinch
        distance = np.linalg.norm(delta)
        waypoint = goal if distance <= STEP else pinch + delta * (STEP / distance)
        q_target = task.solve_ik(waypoint)
        if q_target is None:
            q_target = task.solve_ik(goal)
        q = env.physics.data.qpos[task._joint_qpos[:6]]  # pylint: disable=protected-access
        action = np.zeros(spec.shape)
        action[:6] = gain * (q_target - q)
        action[6:] = spec.maximum[6:]  # close the fingers
        timestep = env.step(np.clip(action, spec.minimum, spec.maximum))
        if timestep.last() or (stop is not None and stop()):
            break
        if distance < 2e-3 and stop is None:
            break
    return timestep


def touch_point(env, target_xyz, *, press_depth=0.01, steps=80):
    """Moves the closed hand over ``target_xyz``, presses down, lifts.

    Returns the last timestep (the move registers while pressing; with the
    arm reset on, the arm then jumps to a new random pose).
    """
    task = env.task
    target = np.asarray(target_xyz, float)
    before = task.moves_registered
    registered = lambda: task.moves_registered > before  # noqa: E731
    pinch = task.pinch_site_position()
    high = max(pinch[2], target[2] + SAFE_HEIGHT)
    for goal, stop in ((np.array([pinch[0], pinch[1], high]), None),
                       (np.array([target[0], target[1], high]), None),
                       (target - (0, 0, press_depth), registered)):
        timestep = _drive(env, goal, steps, stop)
        if timestep.last() or registered():
            return timestep
    return _drive(env, np.array([target[0], target[1], high]), steps // 2)
