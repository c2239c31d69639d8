"""A minimal closed-loop driver for the rolling-ball walker, for tests only.

The real skills live in `skills/`; this is just enough control to script
pushes: turn the face towards the goal, roll forward (negative ``roll``
command) when facing it, slow down near it.
"""

from __future__ import annotations

import numpy as np

CELL = 1.0
BOX_HALF = 0.4
BALL_RADIUS = 0.2


def _wrap(angle: float) -> float:
    return (angle + np.pi) % (2 * np.pi) - np.pi


def drive_to(env, goal, *, max_steps=300, speed=1.0, tol=0.08, reverse_ok=True, on_step=None):
    """Rolls the walker to world point `goal`; returns the last timestep."""
    task = env.task
    goal = np.asarray(goal, float)
    timestep = None
    for _ in range(max_steps):
        delta = goal - task.walker_position()
        dist = float(np.linalg.norm(delta))
        velocity = task.walker_velocity()
        if dist < tol and np.linalg.norm(velocity) < 0.3:
            break
        heading = task.walker_heading()
        err = _wrap(np.arctan2(delta[1], delta[0]) - heading)
        forward = -1.0  # a negative roll command rolls the ball towards its face
        if reverse_ok and abs(err) > np.pi / 2:  # goal behind: back up instead of circling
            err, forward = _wrap(err - np.pi), 1.0
        steer = float(np.clip(-4.0 * err, -1, 1))
        face = np.array([np.cos(heading), np.sin(heading)])
        v_along = float(velocity @ face) * -forward  # speed in the driving direction
        v_want = speed * 1.5 * min(1.0, 1.2 * dist) * max(0.0, np.cos(err)) ** 4
        roll = forward * float(np.clip(1.5 * (v_want - v_along), -1, 1))
        timestep = env.step([roll, steer])
        if on_step is not None:
            on_step(timestep)
        if timestep.last():
            break
    return timestep


def push_box(env, cell, direction, *, on_step=None):
    """Pushes the box in `cell` one cell along `direction` ((drow, dcol)).

    Assumes the cell behind the box is free and reachable in a straight line.
    Returns the timesteps seen while pushing.
    """
    task = env.task
    seen = []

    def record(ts):
        seen.append(ts)
        if on_step is not None:
            on_step(ts)

    dr, dc = direction
    unit = np.array([dc, -dr], float)  # grid rows grow downwards, world y upwards
    box_xy = np.asarray(task.cell_to_world(*cell))
    behind = box_xy - unit * CELL
    drive_to(env, behind, on_step=record)
    if seen and seen[-1].last():
        return seen
    goal = box_xy + unit * CELL - unit * (BOX_HALF + BALL_RADIUS - 0.1)
    drive_to(env, goal, speed=0.6, tol=0.05, reverse_ok=False, max_steps=150, on_step=record)
    if not (seen and seen[-1].last()):
        for _ in range(10):  # back off and let the box settle
            ts = env.step([0.3, 0.0])
            record(ts)
            if ts.last():
                break
    return seen
