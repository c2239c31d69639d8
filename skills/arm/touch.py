"""The touch phase's differential IK: one mink solve per control step that
moves the tool point by a desired velocity, the hand kept pointing as
planned and the wrist damped (the fast shoulder and elbow do the correcting)."""

from __future__ import annotations

import mink
import numpy as np

from skills.arm.geometry import pointing
from skills.arm.model import ArmModel


class TouchIK:
    """Joint velocities for a tool-point velocity, from the ``current`` posture.

    Args:
      arm: the arm model (its ``current`` configuration is the posture now).
      damping, orientation_cost, wrist_damping: the IK weights (against 1 for
        the pinch site's position).
    """

    def __init__(
        self, arm: ArmModel, *, damping: float, orientation_cost: float, wrist_damping: float
    ):
        self.arm = arm
        self.damping = float(damping)
        model = arm.model
        self.frame = mink.FrameTask(
            arm.site_name, "site", position_cost=1.0, orientation_cost=orientation_cost
        )
        cost = np.full(model.nv, 1e-3)
        cost[arm.arm_dof[3:]] = wrist_damping
        self.tasks = [self.frame, mink.DampingTask(model, cost)]

    def command(
        self, tool: np.ndarray, velocity: np.ndarray, direction: np.ndarray, dt: float
    ) -> np.ndarray:
        """The action moving ``tool`` by ``velocity * dt`` with the hand's z axis
        turned (tilt corrected, heading kept) to ``direction``; the arm joints
        scaled within their speed limits, the fingers closing. Raises what
        mink raises when the IK fails."""
        arm = self.arm
        data = arm.current.data
        # The pinch site's target is where it must be for the tool point (fixed
        # in the hand's frame while the fingers are closed) to move by
        # velocity * dt at the target rotation.
        xmat = data.site_xmat[arm.site].reshape(3, 3)
        rotation = pointing(xmat, direction)
        offset = xmat.T @ (tool - data.site_xpos[arm.site])
        pinch = tool + velocity * dt - rotation.as_matrix() @ offset
        self.frame.set_target(mink.SE3.from_rotation_and_translation(rotation, pinch))
        qdot = mink.solve_ik(
            arm.current, self.tasks, dt, "daqp", damping=self.damping, limits=arm.limits
        )
        command = arm.hold()
        command[:6] = qdot[arm.arm_dof]
        ratio = float(np.max(np.abs(command[:6]) / arm.vmax))
        if ratio > 1.0:
            command[:6] /= ratio
        return np.clip(command, arm.low, arm.high)
