"""Movable props of MuJoBan: the boxes."""

from __future__ import annotations

from dm_control import composer, mjcf

from envs.mujoban.arena import BOX_BIT, WALKER_BIT

BOX_RGBA = (0.72, 0.52, 0.3, 1.0)


class Box(composer.Entity):
    """A box that slides on the floor without rotating.

    The box has no contact with the floor: it is carried by two slide joints
    (x, y) added by the task, and is slowed by joint friction loss and damping,
    which gives a floor-like Coulomb stop without the cost of floor contacts.
    It collides with the walker, walls, other boxes and pegs.
    """

    def _build(self, half_size=0.38, half_height=0.3, mass=5.0, name="box"):
        self._mjcf_root = mjcf.RootElement(model=name)
        self.half_size = half_size
        self.half_height = half_height
        self.body = self._mjcf_root.worldbody.add("body", name="body")
        self.geom = self.body.add(
            "geom", name="geom", type="box", size=(half_size, half_size, half_height),
            mass=mass, rgba=BOX_RGBA, contype=BOX_BIT, conaffinity=WALKER_BIT | BOX_BIT,
            condim=3, friction=(0.3, 0.005, 0.0001))

    @property
    def mjcf_model(self):
        return self._mjcf_root
