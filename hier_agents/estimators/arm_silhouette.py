"""`ArmSilhouette`: where a robot arm hides a board in a camera's frames.

The arm's own kinematic model (`envs.description.ArmDescription`) is posed
at observed joints; each of its geoms' convex hulls is projected with a
described camera (`envs.description.CameraDescription`), and, under a light
that casts shadows, so is each geom's shadow on the board's plane. Used by the board
games' camera estimator (`hier_agents.estimators.board_view`).
"""

from __future__ import annotations

import numpy as np

__all__ = ["ArmSilhouette", "PARTS"]

#: What an outline may be of: the arm, its shadow, or both.
PARTS = ("all", "arm", "shadow")


class ArmSilhouette:
    """Where the arm hides the board: the arm's own model (`envs.description.
    ArmDescription`) posed at observed joints, each geom's convex hull
    projected into a camera's frames.

    Args:
      arm: the arm's description (its model compiles on its own).
      camera: the `envs.description.CameraDescription` of the frames.
      shape: (height, width) of the frames.
      light: world (x, y, z) of a point light casting shadows, or None.
      plane_z: the height (m) of the plane the shadows fall on (the board's top).
    """

    def __init__(self, arm, camera, shape, light=None, plane_z: float = 0.0) -> None:
        import mujoco
        from scipy.spatial import ConvexHull

        self._mujoco = mujoco
        self._hull2d = ConvexHull
        self.model = arm.model()
        self.data = mujoco.MjData(self.model)
        self._pinch = self.model.site(arm.pinch_site).id
        self.camera, self.shape = camera, tuple(shape)
        self.light = None if light is None else np.asarray(light, float)
        self.plane_z = float(plane_z)
        m = self.model
        self._geoms, self._local = [], []
        for g in range(m.ngeom):
            if m.geom_rgba[g, 3] <= 0:
                continue
            local = self._geom_points(m, g)
            if local is None:
                continue
            if len(local) > 8:
                local = local[ConvexHull(local).vertices]
            self._geoms.append(g)
            self._local.append(local)
        # All geoms' points in one array (posed and projected at once), and
        # each geom's slice of it.
        counts = [len(local) for local in self._local]
        self._points = np.concatenate(self._local) if counts else np.zeros((0, 3))
        self._owner = np.repeat(np.arange(len(counts)), counts)
        self._slices = [slice(a, b) for a, b in zip(np.cumsum([0] + counts), np.cumsum(counts))]
        # The last posture's outlines: (qpos bytes, arm outlines, shadow outlines).
        self._posed: tuple[bytes, list, list] | None = None

    @staticmethod
    def _geom_points(m, g) -> np.ndarray | None:
        """Points (geom frame) whose convex hull is the geom (or bounds it)."""
        import mujoco

        kind, size = int(m.geom_type[g]), m.geom_size[g]
        if kind == mujoco.mjtGeom.mjGEOM_MESH:
            mesh = int(m.geom_dataid[g])
            start, count = int(m.mesh_vertadr[mesh]), int(m.mesh_vertnum[mesh])
            return np.array(m.mesh_vert[start : start + count], float)
        angles = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        ring = np.stack([np.cos(angles), np.sin(angles)], axis=1)
        if kind in (mujoco.mjtGeom.mjGEOM_CYLINDER, mujoco.mjtGeom.mjGEOM_CAPSULE):
            r, h = size[0], size[1] + (size[0] if kind == mujoco.mjtGeom.mjGEOM_CAPSULE else 0)
            return np.concatenate([np.c_[r * ring, np.full(16, z)] for z in (-h, h)])
        if kind == mujoco.mjtGeom.mjGEOM_BOX:
            corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
            return corners * size
        if kind == mujoco.mjtGeom.mjGEOM_SPHERE:
            r = size[0]
            return np.concatenate(
                [
                    np.c_[r * ring, np.zeros(16)],
                    np.c_[r * ring[:, :1], np.zeros(16), r * ring[:, 1:]],
                    np.c_[np.zeros(16), r * ring],
                ]
            )
        return None

    def pinch(self, qpos) -> np.ndarray:
        """The pinch site's world position (x, y, z; m) with the arm at ``qpos``."""
        d = self.data
        d.qpos[:] = np.asarray(qpos, float)
        self._mujoco.mj_kinematics(self.model, d)
        return d.site_xpos[self._pinch].copy()

    def outlines(self, qpos, part: str = "all") -> list[np.ndarray]:
        """Per geom, its projected outline (``part`` "arm" or "all"), and with
        a ``light`` its shadow's ("shadow" or "all"): (k, 2) pixel (row, col)
        vertices of a convex polygon, counter-clockwise in (col, row). A geom
        seen edge-on (a degenerate outline) has none."""
        if part not in PARTS:
            raise ValueError(f"part must be one of {PARTS}, got {part!r}")
        arm, shadow = self._posed_outlines(np.asarray(qpos, float))
        out = []
        for g in range(len(self._geoms)):
            if part != "shadow" and arm[g] is not None:
                out.append(arm[g])
            if part != "arm" and shadow[g] is not None:
                out.append(shadow[g])
        return out

    def _posed_outlines(self, qpos: np.ndarray) -> tuple[list, list]:
        """Per geom, its outline and its shadow's (None: none) with the arm
        at ``qpos``; the last posture's are kept (a frame asks for several
        parts)."""
        key = qpos.tobytes()
        if self._posed is not None and self._posed[0] == key:
            return self._posed[1], self._posed[2]
        m, d = self.model, self.data
        d.qpos[:] = qpos
        self._mujoco.mj_kinematics(m, d)
        geoms = self._geoms
        rotations = d.geom_xmat[geoms].reshape(-1, 3, 3)[self._owner]
        world = d.geom_xpos[geoms][self._owner] + np.einsum("nij,nj->ni", rotations, self._points)
        arm = self._hulls(self.camera.project(world, self.shape), None)
        shadow = [None] * len(geoms)
        if self.light is not None:
            cast, casting = self._shadow(world)
            shadow = self._hulls(self.camera.project(cast, self.shape), casting)
        self._posed = (key, arm, shadow)
        return arm, shadow

    def _hulls(self, px: np.ndarray, keep) -> list:
        """Per geom, the convex hull of its projected points ``px`` (those
        ``keep`` marks, all when None): (k, 2) vertices, counter-clockwise in
        (col, row), or None when fewer than 3 points or degenerate."""
        out = []
        for part in self._slices:
            points = px[part] if keep is None else px[part][keep[part]]
            hull = None
            if len(points) >= 3:
                try:
                    hull = points[self._hull2d(points[:, ::-1]).vertices]
                except Exception:  # a degenerate projection (edge-on): none
                    hull = None
            out.append(hull)
        return out

    def _shadow(self, world: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(cast, casting): where the light casts the points ``world`` (k, 3)
        on the plane ``plane_z`` (the central projection from the light),
        and which points cast one: not those at or above the light, nor
        below the plane (their rows of ``cast`` are the points themselves)."""
        light = self.light
        assert light is not None  # called only with a light
        casting = (world[:, 2] < light[2] - 1e-6) & (world[:, 2] >= self.plane_z)
        points = world[casting]
        t = (self.plane_z - light[2]) / (points[:, 2] - light[2])
        cast = world.copy()
        cast[casting] = light + t[:, None] * (points - light)
        return cast, casting

    def hidden(self, qpos, centres, radius, part: str = "all") -> np.ndarray:
        """(n,) bool: which discs (``centres`` (n, 2) pixel row, col and
        ``radius`` (n,) pixels) an outline of ``part`` (`outlines`) covers
        or comes within their radius of (a convex polygon's largest signed
        edge distance); a negative radius asks for the centres that deep
        inside one outline."""
        centres = np.asarray(centres, float)
        radius = np.broadcast_to(np.asarray(radius, float), (len(centres),))
        polys = self.outlines(qpos, part)
        if not polys or not len(centres):
            return np.zeros(len(centres), bool)
        reach = radius.max(initial=0.0)
        # All outlines at once: each one's edges (col, row), counter-clockwise,
        # repeated cyclically up to the longest outline's count (a repeated
        # edge leaves the largest edge distance as it is); the distances of
        # the (centre, outline) pairs within an outline's box grown by the
        # largest radius only.
        low = np.stack([poly.min(axis=0) for poly in polys]) - reach
        high = np.stack([poly.max(axis=0) for poly in polys]) + reach
        near = np.all((centres[:, None] >= low[None]) & (centres[:, None] <= high[None]), axis=2)
        at, of = np.nonzero(near)
        hidden = np.zeros(len(centres), bool)
        if not len(at):
            return hidden
        count = max(len(poly) for poly in polys)
        steps = np.arange(count)
        a = np.stack([poly[steps % len(poly), ::-1] for poly in polys])  # (P, K, 2)
        b = np.stack([poly[(steps + 1) % len(poly), ::-1] for poly in polys])
        edge = b - a
        normal = np.stack([edge[..., 1], -edge[..., 0]], axis=-1)
        normal /= np.maximum(np.linalg.norm(normal, axis=-1, keepdims=True), 1e-9)
        rel = centres[at][:, None, ::-1] - a[of]  # (pairs, K, 2)
        dist = (rel * normal[of]).sum(-1).max(axis=1)  # outward normals of a CCW hull
        hidden[at[dist < radius[at]]] = True
        return hidden
