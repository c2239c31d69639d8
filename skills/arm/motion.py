"""Joint-space motions of the arm skill: along a straight line in joint space
to a planned posture, and straight up with the shoulder and elbow."""

from __future__ import annotations

import math

import numpy as np

from skills.arm.model import ArmModel


def line_command(
    arm: ArmModel,
    q: np.ndarray,
    arm_qvel: np.ndarray,
    goal: np.ndarray,
    accel: np.ndarray,
    dt: float,
    brake: bool,
) -> tuple[np.ndarray, float]:
    """Joint-velocity command along the straight line in joint space from
    ``q`` to ``goal`` (full qpos of the arm model), the fingers closing.

    The slowest joint runs at its limit and the others in step. With
    ``brake`` (travel) the speed along the line also ramps up from the
    current velocities (``arm_qvel``, the six arm joints) and brakes within
    every joint's acceleration ``accel``, so the posture is reached without
    overshoot; without it (the short descent) it is full speed at once.

    Returns (command, seconds to ``goal`` at full speed).
    """
    delta = arm.joint_delta(q, goal)
    scaled = np.abs(delta) / arm.vmax
    remaining = float(np.max(scaled))  # seconds at full speed
    command = arm.hold()
    if remaining < 1e-6:
        return command, remaining
    speed = 1.0  # fraction of full speed along the line
    if brake:
        moving = np.abs(delta) > 1e-9
        # Acceleration along the line (fraction of full speed per second).
        rate = float(np.min(accel[moving] * remaining / np.abs(delta[moving])))
        slowest = int(np.argmax(scaled))
        current = float(
            np.clip(arm_qvel[slowest] * np.sign(delta[slowest]) / arm.vmax[slowest], 0.0, 1.0)
        )
        half = 0.5 * rate * dt  # braking a step late
        speed = min(1.0, current + rate * dt, math.sqrt(2 * rate * remaining + half * half) - half)
    command[:6] = delta / remaining * speed
    return np.clip(command, arm.low, arm.high), remaining


def lift_command(arm: ArmModel, tool: np.ndarray, speed: float) -> np.ndarray:
    """Raises the tool point ``tool`` (of the ``current`` posture) at
    ``speed`` (m/s) with the shoulder and elbow, the fingers closing; within
    the action's bounds (a joint scaled to its full speed can round past it)."""
    command = arm.hold()
    big = np.array([1, 2])  # shoulder, elbow (the base turns about the vertical)
    jz = arm.tool_jacobian_z(tool)[big]
    norm = float(jz @ jz)
    if norm > 1e-9:
        qdot = jz * (speed / norm)
        qdot /= max(1.0, float(np.max(np.abs(qdot) / arm.vmax[big])))
        command[big] = qdot
    return np.clip(command, arm.low, arm.high)
