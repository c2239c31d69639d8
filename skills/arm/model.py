"""`ArmModel`: the arm's own kinematic model and its fingertip geometry.

Built from the public `envs.description.ArmDescription` (``model()`` compiles
only the arm and hand, mounted where they are in the environment; its qpos
is the ``arm/joints_pos`` observation). The skill sets the observed joint
angles into this model's own data and runs kinematics on it; nothing here
touches the environment's simulation.
"""

from __future__ import annotations

import math

import mink
import mujoco
import numpy as np

from skills.arm.geometry import enclosing_circle

#: Accelerations (rad/s²) the velocity servos reach on the six arm joints,
#: measured from rest with a full-range command (the wrist's force limit of
#: 6.8 N m makes it slow).
JOINT_ACCELERATION = np.array([6.5, 4.8, 5.8, 2.8, 2.8, 2.8])
#: A known-good arm posture above the board.
HOME_ARM_QPOS = np.array([1.24, 3.89, 2.13, 5.79, 1.64, 3.89])

#: The fingertip geoms (their names' last part) whose meshes lead a touch.
TIP_NAMES = ("finger_tip_1", "finger_tip_2", "finger_tip_3")


class ArmModel:
    """The arm's kinematics: joint indices and limits, the fingertip meshes,
    the tool point, the fingertips' footprint.

    Two mink configurations of the model: ``current`` (the observed posture,
    `set_posture`) and ``scratch`` (posture IK and footprint probes).

    Args:
      arm: the `ArmDescription`.
      band: fingertip vertices within this height (m) of the lowest one lead.
    """

    def __init__(self, arm, *, band: float):
        self.description = arm
        self.band = float(band)
        self.model = model = arm.model()
        ids = [
            mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_JOINT, name) for name in arm.joint_names
        ]
        if min(ids) < 0 or len(ids) != 9:
            raise ValueError(f"the arm model lacks some of the joints {arm.joint_names}")
        # Observation order (arm/joints_pos) -> the model's qpos and dofs.
        self.obs_qpos = model.jnt_qposadr[ids].copy()
        self.obs_dof = model.jnt_dofadr[ids].copy()
        self.arm_qpos, self.finger_qpos = self.obs_qpos[:6], self.obs_qpos[6:]
        self.arm_dof = self.obs_dof[:6]
        self.low = np.asarray(arm.action_minimum, float)
        self.high = np.asarray(arm.action_maximum, float)
        self.vmax = self.high[:6]
        self.site_name = arm.pinch_site
        self.site = mujoco.mj_name2id(model, mujoco.mjtObj.mjOBJ_SITE, arm.pinch_site)
        if self.site < 0:
            raise ValueError(f"the arm model has no site {arm.pinch_site!r}")
        # Continuous arm joints (no range): differences are taken modulo 2 pi.
        self.wrap = ~model.jnt_limited[np.asarray(ids[:6])].astype(bool)
        self.fingers_closed = model.jnt_range[np.asarray(ids[6:]), 1].copy()
        self.limits = [mink.ConfigurationLimit(model)]
        self.current = mink.Configuration(model)
        self.scratch = mink.Configuration(model)
        # The arm's base (the body of its first joint turns about the vertical).
        base_body = int(model.jnt_bodyid[ids[0]])
        self.current.update(model.qpos0.copy())
        self._base_xy = self.current.data.xpos[base_body][:2].copy()
        # Fingertip mesh vertices in their geoms' frames.
        self.tip_geoms, self.tip_verts = [], []
        for g in range(model.ngeom):
            name = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) or ""
            if name.split("/")[-1] in TIP_NAMES and model.geom_dataid[g] >= 0:
                mesh = model.geom_dataid[g]
                start, count = model.mesh_vertadr[mesh], model.mesh_vertnum[mesh]
                self.tip_geoms.append(g)
                self.tip_verts.append(model.mesh_vert[start : start + count].astype(float).copy())
        if len(self.tip_geoms) != 3:
            raise ValueError(
                f"expected the Jaco hand's three fingertip meshes, found {len(self.tip_geoms)}"
            )

    # -- the observed posture ----------------------------------------------------

    def set_posture(self, joints_pos) -> np.ndarray:
        """Sets the observed joint angles (``arm/joints_pos`` order) into
        ``current`` and runs its kinematics; returns the model's qpos."""
        q = self.model.qpos0.copy()
        q[self.obs_qpos] = np.asarray(joints_pos, float)
        self.current.update(q)
        return q

    def arm_velocity(self, joints_vel) -> np.ndarray:
        """The six arm joints' velocities (rad/s) from ``arm/joints_vel``."""
        return np.asarray(joints_vel, float)[:6]

    def joint_delta(self, q_from: np.ndarray, q_to: np.ndarray) -> np.ndarray:
        """Arm joint differences ``q_to - q_from`` (6), the short way round."""
        delta = q_to[self.arm_qpos] - q_from[self.arm_qpos]
        delta[self.wrap] = (delta[self.wrap] + np.pi) % (2 * np.pi) - np.pi
        return delta

    def base_xy(self) -> np.ndarray:
        """World (x, y) of the arm's base."""
        return self._base_xy.copy()

    # -- fingertips and the tool point ---------------------------------------------

    def tool(self, data, tips=None) -> tuple[np.ndarray, float]:
        """(tool point, tip spread) of the kinematics in ``data``.

        The *leading* fingertips (unless ``tips`` names them) are those whose
        lowest point is within ``band`` of the lowest one (all three when the
        hand points down; a tilted hand may lead with one or two). The tool
        point is the centre (x, y) of the smallest circle around the leading
        tips' lowest points, at the lowest height; the spread is that circle's
        radius.
        """
        lows = self.tip_lows(data)
        lowest = lows[:, 2].min()
        leading = lows[list(tips if tips is not None else self.leading(lows))]
        if len(leading) == 3:
            centre, spread = enclosing_circle(leading[:, :2])
        elif len(leading) == 2:
            centre = leading[:, :2].mean(axis=0)
            spread = 0.5 * float(np.linalg.norm(leading[0, :2] - leading[1, :2]))
        else:
            centre, spread = leading[0, :2], 0.0
        return np.array([centre[0], centre[1], lowest]), spread

    def leading(self, lows: np.ndarray) -> tuple:
        """Indices of the leading fingertips, from their lowest points."""
        return tuple(np.flatnonzero(lows[:, 2] <= lows[:, 2].min() + self.band))

    def tip_heights(self, data) -> list[np.ndarray]:
        """Each fingertip mesh's vertex heights (world z) in ``data``."""
        return [
            data.geom_xpos[g][2] + verts @ data.geom_xmat[g][6:9]
            for g, verts in zip(self.tip_geoms, self.tip_verts)
        ]

    def tip_points(self, data, tip: int, index) -> np.ndarray:
        """World coordinates of fingertip ``tip``'s vertices ``index``."""
        g = self.tip_geoms[tip]
        return data.geom_xpos[g] + self.tip_verts[tip][index] @ data.geom_xmat[g].reshape(3, 3).T

    def tip_lows(self, data) -> np.ndarray:
        """(3, 3): each fingertip mesh's lowest point in ``data``."""
        return np.array(
            [
                self.tip_points(data, i, int(np.argmin(z)))
                for i, z in enumerate(self.tip_heights(data))
            ]
        )

    def sweep(self, q: np.ndarray, finger_reach: float, band: float, samples: int = 3):
        """The fingertips' footprint while the fingers close from ``q`` by up to
        ``finger_reach`` radians, the arm fixed at ``q`` (in ``scratch``).

        Returns (points (k, 3), lowest height): for every sample, the fingertip
        mesh vertices within ``band`` (m) of the lowest one -- what may touch
        a pad in the control step of the first contact -- stacked; and the
        lowest height of all samples.
        """
        config = self.scratch
        start = q[self.finger_qpos]
        points, lowest = [], np.inf
        for f in np.linspace(0.0, 1.0, samples):
            probe = q.copy()
            probe[self.finger_qpos] = np.minimum(start + f * finger_reach, self.fingers_closed)
            config.update(probe)
            heights = self.tip_heights(config.data)
            low = min(float(z.min()) for z in heights)
            for tip, z in enumerate(heights):
                index = np.flatnonzero(z <= low + band)
                if len(index):
                    points.append(self.tip_points(config.data, tip, index))
            lowest = min(lowest, low)
        return np.concatenate(points), lowest

    def footprint_offset(
        self, q: np.ndarray, centre_xy: np.ndarray, finger_reach: float, band: float
    ) -> float:
        """Largest distance along x or y (the pads are squares) from
        ``centre_xy`` of the fingertips' footprint (``band``) at ``q`` while
        the fingers close by up to ``finger_reach``."""
        points, _ = self.sweep(q, finger_reach, band, 3 if finger_reach > 0 else 1)
        return float(np.max(np.abs(points[:, :2] - centre_xy[:2])))

    def tool_jacobian_z(self, tool: np.ndarray) -> np.ndarray:
        """d(tool height)/d(arm joint angles) (6), at the ``current`` posture."""
        jacp = np.zeros((3, self.model.nv))
        mujoco.mj_jac(
            self.model, self.current.data, jacp, None, tool, int(self.model.site_bodyid[self.site])
        )
        return jacp[2, self.arm_dof]

    def tilt(self, data) -> float:
        """Angle (degrees) between the pinch site's z axis and straight down."""
        return math.degrees(math.acos(float(np.clip(-data.site_xmat[self.site][8], -1, 1))))

    def hold(self) -> np.ndarray:
        """Arm joints still, fingers closing (at full speed)."""
        command = np.zeros(self.low.shape)
        command[6:] = self.high[6:]
        return command
