"""Movable props of MuJoBan: the boxes."""

from __future__ import annotations

from dm_control import composer, mjcf

from envs.mujoban.arena import BOX_BIT, BOX_RGBA, WALKER_BIT

#: The original task's box (physics_planning_games, mujoban.py: ``_BOX_SIZE``,
#: ``_BOX_HEIGHT``, ``_BOX_MASS``): half-size 0.4 x 0.4, half-height 0.15 m, 2.5 kg.
BOX_HALF_SIZE = 0.4
BOX_HALF_HEIGHT = 0.15
BOX_MASS = 2.5
#: Box-floor contact (the original's ``_BOX_FRICTION`` contact pair): sliding,
#: torsional, rolling friction, with ``condim=6``.
BOX_FLOOR_FRICTION = (0.5, 0.005, 0.0001)


class Box(composer.Entity):
    """A box that slides on the floor without rotating, as in the original task.

    The task carries it by three slide joints (x, y, z; no rotation, no joint
    friction loss or damping) and adds a box-floor contact pair with friction
    `BOX_FLOOR_FRICTION` (``condim=6``): a pushed box slides on floor friction
    and coasts a little after the push. The geom keeps MuJoCo's default
    friction (1, 0.005, 0.0001) and ``condim=3``, so its contacts with the
    walker, walls, pegs and other boxes combine as in the original (the
    larger of the two geoms' values).
    """

    def _build(
        self, half_size=BOX_HALF_SIZE, half_height=BOX_HALF_HEIGHT, mass=BOX_MASS, name="box"
    ):
        self._mjcf_root = mjcf.RootElement(model=name)
        self.half_size = half_size
        self.half_height = half_height
        self.body = self._mjcf_root.worldbody.add("body", name="body")
        self.geom = self.body.add(
            "geom",
            name="geom",
            type="box",
            size=(half_size, half_size, half_height),
            mass=mass,
            rgba=BOX_RGBA,
            contype=BOX_BIT,
            conaffinity=WALKER_BIT | BOX_BIT,
            condim=3,
            friction=(1.0, 0.005, 0.0001),
        )

    @property
    def mjcf_model(self):
        return self._mjcf_root
