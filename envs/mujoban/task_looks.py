"""Looks of the MuJoBan task (`envs.mujoban.task.Mujoban`): the public
description, the labmaze wall and floor textures drawn per episode, and the
pad and box colours that show which pads are covered.

`LooksMixin` is one of `Mujoban`'s bases; its methods read the attributes
`Mujoban.after_compile` sets (``_model``, material and texture ids, pad and
box geom ids) and the episode state (``_covered``, ``_box_reference``).
"""

from __future__ import annotations

from typing import Any

import numpy as np

from envs.mujoban import arena as arena_lib
from envs.rendering import Marker

#: MuJoCo's texture role of a material's base colour (``mjTEXROLE_RGB``).
_TEXROLE_RGB = 1
#: Radius of the render-only disc drawn over a peg, in peg radii.
PEG_MARKER_SCALE = 2.0
#: The rolling ball's radius (dm_control's ``RollingBallWithHead`` shell), metres.
BALL_RADIUS = 0.2
#: Its ear spheres' colours (dm_control's ``add_ears``): red at the head's +x,
#: blue at -x.
EAR_RGBA = ((0.7, 0.0, 0.0, 1.0), (0.0, 0.0, 0.7, 1.0))


class LooksMixin:
    """Description, appearance (textures) and pad colours of `Mujoban`."""

    # Set by `Mujoban` (its arena, compiled-model indices and episode state).
    _arena: arena_lib.MujobanArena
    _model: Any  # mujoco.MjModel (mujoco has no type stubs)
    _wall_mats: np.ndarray
    _wall_tex_ids: list[int]
    _floor_mat: int
    _floor_tex_ids: list[int]
    _box_geom_ids: np.ndarray
    _pad_ids: np.ndarray
    _num_boxes: int
    _pad_tolerance: float
    _box_reference: list
    _covered: tuple[bool, ...]
    _target_xy: list[tuple[float, float]]

    def description(self):
        """The public `envs.description.MujobanDescription` of this task."""
        from envs.description import CameraDescription, MujobanDescription, MujobanLooks

        arena = self._arena
        cam = arena.top_camera
        top = CameraDescription(
            "top_camera",
            tuple(float(v) for v in cam.pos),
            tuple(float(v) for v in cam.xyaxes),
            float(cam.fovy),
            (self._cameras["top_camera"].height, self._cameras["top_camera"].width)
            if "top_camera" in self._cameras
            else None,
            multisamples=arena.multisamples,
        )
        box = self._boxes[0]
        return MujobanDescription(
            grid_shape=tuple(arena.grid_shape),
            cell_size=float(arena.cell_size),
            pegs=bool(arena.pegs),
            max_boxes=len(self._boxes),
            control_timestep=float(self.control_timestep),
            time_limit_steps=int(self.time_limit_steps),
            pad_tolerance=self._pad_tolerance / arena.cell_size,
            box_half=float(box.half_size),
            box_half_height=float(box.half_height),
            ball_radius=BALL_RADIUS,
            peg_radius=arena_lib.PEG_RADIUS,
            top_camera=top,
            looks=MujobanLooks(
                box=arena_lib.BOX_RGBA,
                box_on_pad=arena_lib.BOX_ON_PAD_RGBA,
                pad=arena_lib.PAD_RGBA,
                pad_covered=arena_lib.PAD_COVERED_RGBA,
                right_ear=EAR_RGBA[0],
                left_ear=EAR_RGBA[1],
                headlight_ambient=arena_lib.HEADLIGHT_AMBIENT,
                headlight_diffuse=arena_lib.HEADLIGHT_DIFFUSE,
            ),
        )

    def render_markers(self):
        """Render-only discs over the pegs (none without pegs): a peg is 0.1 m
        across, about 2 pixels of a 256-pixel top view, so `Environment.render`
        draws each as a light disc of twice its radius on its top (hidden by
        walls where the peg is). Observed camera frames show the pegs as they are."""
        markers = getattr(self, "_peg_markers", None)
        if markers is None:
            markers = tuple(
                Marker(
                    (float(p.pos[0]), float(p.pos[1]), arena_lib.PEG_HEIGHT),
                    PEG_MARKER_SCALE * arena_lib.PEG_RADIUS,
                )
                for p in self._arena.pegs
            )
            self._peg_markers = markers
        return markers

    @property
    def appearance(self) -> tuple[str, str]:
        """This episode's (wall texture, floor texture): labmaze ``style_01``
        names such as ``("yellow", "blue_team")`` (see `appearances`)."""
        m = self._model
        walls, floors = self.appearances()
        return (
            walls[self._wall_tex_ids.index(int(m.mat_texid[self._wall_mats[0], _TEXROLE_RGB]))],
            floors[self._floor_tex_ids.index(int(m.mat_texid[self._floor_mat, _TEXROLE_RGB]))],
        )

    def _draw_appearance(self, rng: np.random.Generator) -> None:
        """Draws one labmaze texture for the walls and one for the floor from
        ``rng`` (the original draws them from numpy's global generator)."""
        walls, floors = self.appearances()
        self.set_appearance(
            walls[int(rng.integers(len(walls)))], floors[int(rng.integers(len(floors)))]
        )

    def appearances(self) -> tuple[tuple[str, ...], tuple[str, ...]]:
        """The wall and floor texture names an episode may draw."""
        arena = self._arena
        return (
            tuple(t.name.removeprefix("wall_") for t in arena.wall_textures),
            tuple(t.name.removeprefix("floor_") for t in arena.floor_textures),
        )

    def set_appearance(self, wall: str, floor: str) -> None:
        """Shows the walls with texture ``wall`` and the floor with ``floor``
        (names from `appearances`) until the next episode draws again.
        Raises ValueError for an unknown name."""
        walls, floors = self.appearances()
        for kind, name, names in (("wall", wall, walls), ("floor", floor, floors)):
            if name not in names:
                raise ValueError(f"unknown {kind} texture {name!r}; one of {', '.join(names)}")
        m = self._model
        m.mat_texid[self._wall_mats, _TEXROLE_RGB] = self._wall_tex_ids[walls.index(wall)]
        m.mat_texid[self._floor_mat, _TEXROLE_RGB] = self._floor_tex_ids[floors.index(floor)]

    def _paint_pads(self) -> None:
        """The original's colours: a covered pad green and the box covering
        it (the first in box order) blue, other pads red, other boxes yellow."""
        rgba = self._model.geom_rgba
        rgba[self._box_geom_ids[: self._num_boxes]] = arena_lib.BOX_RGBA
        tol = self._pad_tolerance
        boxes = self._box_reference
        for k, covered in enumerate(self._covered):
            rgba[self._pad_ids[k]] = arena_lib.PAD_COVERED_RGBA if covered else arena_lib.PAD_RGBA
            if covered:
                tx, ty = self._target_xy[k]
                i = next(
                    i
                    for i, (bx, by) in enumerate(boxes)
                    if abs(tx - bx) <= tol and abs(ty - by) <= tol
                )
                rgba[self._box_geom_ids[i]] = arena_lib.BOX_ON_PAD_RGBA
