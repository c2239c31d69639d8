"""The arm's random pose of the board task (`envs.boards.task.BoardTask`): the
original's arm reset (the grip site at a random point of the TCP box,
pointing down with a random yaw, by IK with mink, rejecting poses that
collide) and the pinch-site IK that tests and scripts use.

`ArmPoseMixin` is one of `BoardTask`'s bases; it reads the attributes
`BoardTask.after_compile` sets (``_model``, ``_data``, ``_joint_qpos``,
``_arm_wrap``, ``_finger_range``, the robot geom masks, site names) and
counts failed resets in ``ik_failures``.
"""

from __future__ import annotations

import math

import mink
import mujoco
import numpy as np

#: A known-good arm posture with the hand above the board pointing down; the
#: IK for random poses starts from it and is regularised towards it.
HOME_ARM_QPOS = np.array([4.38, 3.89, 2.13, 5.79, 1.64, 3.89])
#: Orientation of a Jaco site pointing straight down (w, x, y, z), as
#: dm_control's ``manipulators.base.DOWN_QUATERNION``.
DOWN_QUAT = np.array([0.0, 0.70710678118, 0.70710678118, 0.0])
#: The original's box of tool-centre-point positions for the arm reset.
TCP_LOW = np.array([-0.1, -0.1, 0.2])
TCP_HIGH = np.array([0.1, 0.1, 0.4])
_REJECTION_SAMPLES = 10


def _quat_mul(a, b):
    """Hamilton product ``a * b`` of quaternions (w, x, y, z)."""
    w1, x1, y1, z1 = a
    w2, x2, y2, z2 = b
    return np.array(
        [
            w1 * w2 - x1 * x2 - y1 * y2 - z1 * z2,
            w1 * x2 + x1 * w2 + y1 * z2 - z1 * y2,
            w1 * y2 - x1 * z2 + y1 * w2 + z1 * x2,
            w1 * z2 + x1 * y2 - y1 * x2 + z1 * w2,
        ]
    )


class ArmPoseMixin:
    """Random arm poses (the arm reset) and IK of `BoardTask`."""

    # Set by `BoardTask` (compiled-model indices).
    _model: mujoco.MjModel
    _data: mujoco.MjData
    _joint_qpos: np.ndarray
    _arm_wrap: np.ndarray
    _finger_range: np.ndarray
    _is_arm: np.ndarray
    _is_hand: np.ndarray
    _pinch_name: str
    _tcp_name: str
    ik_failures: int
    # The IK problems, built on first use (None until then).
    _ik: tuple | None
    _tcp_ik: tuple | None

    def _place_arm(self, rng) -> None:
        """The original's arm reset: the grip site at a random point of the
        TCP box, pointing down with a random yaw; fingers and velocities kept."""
        d, m = self._data, self._model
        arm_qpos = self._joint_qpos[:6]
        before = d.qpos[arm_qpos].copy()
        for _ in range(_REJECTION_SAMPLES):
            target = rng.uniform(TCP_LOW, TCP_HIGH)
            yaw = rng.uniform(-math.pi, math.pi)
            quat = _quat_mul([math.cos(yaw / 2), 0.0, 0.0, math.sin(yaw / 2)], DOWN_QUAT)
            arm_q = self._solve_tcp(target, quat)
            if arm_q is None:
                continue
            d.qpos[arm_qpos] = arm_q
            mujoco.mj_forward(m, d)
            if not self._arm_collides():
                return
        self.ik_failures += 1
        d.qpos[arm_qpos] = before
        mujoco.mj_forward(m, d)

    def _arm_collides(self) -> bool:
        """Contacts of the arm with itself, the hand or the board (not hand-hand)."""
        ncon = self._data.ncon
        if not ncon:
            return False
        contact = self._data.contact
        g = contact.geom[:ncon]
        touching = contact.dist[:ncon] <= 0
        arm, hand = self._is_arm[g], self._is_hand[g]
        robot = arm | hand
        relevant = (
            (arm[:, 0] & robot[:, 1]) | (robot[:, 0] & arm[:, 1]) | (robot[:, 0] != robot[:, 1])
        )
        return bool(np.any(relevant & touching))

    def _ik_problem(self, site: str, *, orientation_cost: float, fingers=None):
        """A mink problem for ``site``: (configuration, frame task, posture task
        regularising towards the home posture, that home posture)."""
        config = mink.Configuration(self._model)
        frame = mink.FrameTask(site, "site", position_cost=1.0, orientation_cost=orientation_cost)
        posture = mink.PostureTask(self._model, cost=1e-3)
        home = config.q.copy()
        home[self._joint_qpos[:6]] = HOME_ARM_QPOS
        if fingers is not None:
            home[self._joint_qpos[6:]] = fingers
        posture.set_target(home)
        return config, frame, posture, home

    def _solve_tcp(self, target, quat) -> np.ndarray | None:
        """Arm joints putting the grip site at ``target`` with orientation ``quat``."""
        if self._tcp_ik is None:
            self._tcp_ik = self._ik_problem(self._tcp_name, orientation_cost=1.0)
        config, frame, posture, home = self._tcp_ik
        frame.set_target(
            mink.SE3.from_rotation_and_translation(
                mink.SO3(np.asarray(quat)), np.asarray(target, float)
            )
        )
        q = home.copy()
        q[self._joint_qpos[6:]] = self._data.qpos[self._joint_qpos[6:]]
        config.update(q)
        for _ in range(200):
            velocity = mink.solve_ik(config, [frame, posture], 0.05, "daqp", damping=1e-3)
            config.integrate_inplace(velocity, 0.05)
            error = frame.compute_error(config)
            if np.linalg.norm(error[:3]) < 1e-3 and np.linalg.norm(error[3:]) < 1e-2:
                break
        else:
            return None
        arm_q = config.q[self._joint_qpos[:6]].copy()
        # Continuous joints in [0, 2 pi), as dm_control's IK canonicalises them.
        arm_q[self._arm_wrap] = np.mod(arm_q[self._arm_wrap], 2 * np.pi)
        return arm_q

    def solve_ik(self, target) -> np.ndarray | None:
        """Arm joint angles (6) putting the pinch site at ``target`` pointing down.

        Starts from a home posture above the board (then, failing that, from
        the current posture) and is regularised towards it; None if it does
        not converge to 2 mm. (For tests and scripts.)
        """
        target = np.asarray(target, dtype=np.float64)
        if self._ik is None:
            problem = self._ik_problem(
                self._pinch_name, orientation_cost=0.05, fingers=self._finger_range[:, 0]
            )
            self._ik = (*problem, [mink.ConfigurationLimit(self._model)])
        config, frame, posture, home, limits = self._ik
        frame.set_target(mink.SE3.from_rotation_and_translation(mink.SO3(DOWN_QUAT), target))
        current = home.copy()
        current[self._joint_qpos[:6]] = self._data.qpos[self._joint_qpos[:6]]
        for start in (home, current):
            config.update(start)
            for _ in range(150):
                velocity = mink.solve_ik(
                    config, [frame, posture], 0.05, "daqp", damping=1e-3, limits=limits
                )
                config.integrate_inplace(velocity, 0.05)
                if np.linalg.norm(frame.compute_error(config)[:3]) < 2e-3:
                    return config.q[self._joint_qpos[:6]].copy()
        return None
