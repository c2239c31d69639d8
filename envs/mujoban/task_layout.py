"""Level layout of the MuJoBan task (`envs.mujoban.task.Mujoban`): putting a
`Level` into the fixed arena (walls as collision cells and render slabs,
target pads, the static entity layer) at every reset.

`LayoutMixin` is one of `Mujoban`'s bases; it reads the compiled ids
`Mujoban.after_compile` sets and sets ``level``, ``_targets``,
``_target_xy``, ``_num_boxes``, ``_initial_box_cells``, ``_box_cells``,
``_active_box_qpos`` and ``_static_layer``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

import numpy as np

from envs.mujoban import arena as arena_lib
from envs.mujoban.levels import Level, LevelError
from envs.mujoban.task_observations import TARGET, WALL

_PARKED_Z = -20.0


class LayoutMixin:
    """Loads a level into `Mujoban`'s arena."""

    # Set by `Mujoban` (its arena and compiled-model indices).
    _arena: arena_lib.MujobanArena
    _model: Any  # mujoco.MjModel (mujoco has no type stubs)
    _data: Any  # mujoco.MjData
    _boxes: list
    _wall_ids: np.ndarray
    _slab_ids: np.ndarray
    _slab_mats: np.ndarray
    _box_qpos_list: list[tuple[int, ...]]
    _pad_ids: np.ndarray
    level: Level | None  # the level loaded (None before the first episode)

    if TYPE_CHECKING:  # `Mujoban`'s properties

        @property
        def grid_shape(self) -> tuple[int, int]: ...

        @property
        def cell_size(self) -> float: ...

    def _set_level(self, level: Level) -> None:
        height, width = self.grid_shape
        if level.height > height or level.width > width:
            raise LevelError(
                f"level is {level.height}x{level.width}, larger than the arena's "
                f"{height}x{width} (raise grid_shape)",
                path=None,
                index=None,
            )
        if len(level.boxes) > len(self._boxes):
            raise LevelError(
                f"level has {len(level.boxes)} boxes, the arena holds at most "
                f"{len(self._boxes)} (raise max_boxes)",
                path=None,
                index=None,
            )
        if (level.height, level.width) != (height, width):
            level = level.padded(height, width)
        self.level = level
        m = self._model
        walls = np.zeros((height, width), bool)
        for r, c in level.walls:
            walls[r, c] = True
        ids = self._wall_ids.ravel()
        m.geom_contype[ids] = np.where(walls.ravel(), arena_lib.WALKER_BIT, 0)
        m.geom_conaffinity[ids] = np.where(
            walls.ravel(), arena_lib.WALKER_BIT | arena_lib.BOX_BIT, 0
        )
        cell = self.cell_size
        rects = arena_lib.wall_rectangles(walls)
        self._walls_drawn_per_cell = len(rects) > len(self._slab_ids)
        if self._walls_drawn_per_cell:
            rects = []
            m.geom_group[ids] = np.where(walls.ravel(), 0, arena_lib.HIDDEN_GROUP)
        else:
            m.geom_group[ids] = arena_lib.HIDDEN_GROUP
        for k, slab in enumerate(self._slab_ids):
            if k < len(rects):
                r0, c0, r1, c1 = rects[k]
                x0, y0 = self._arena.cell_centre(r0, c0)
                x1, y1 = self._arena.cell_centre(r1 - 1, c1 - 1)
                m.geom_pos[slab] = ((x0 + x1) / 2, (y0 + y1) / 2, arena_lib.WALL_HEIGHT / 2)
                m.geom_size[slab] = (
                    (c1 - c0) * cell / 2,
                    (r1 - r0) * cell / 2,
                    arena_lib.WALL_HEIGHT / 2,
                )
                m.mat_texrepeat[self._slab_mats[k]] = (c1 - c0, r1 - r0)
                m.geom_group[slab] = 0
            else:
                m.geom_pos[slab] = (0, 0, _PARKED_Z)
                m.geom_group[slab] = arena_lib.HIDDEN_GROUP
        self._targets = sorted(level.targets)
        self._num_boxes = len(level.boxes)
        self._initial_box_cells = sorted(level.boxes)
        self._active_box_qpos = self._box_qpos_list[: self._num_boxes]
        self._box_cells = tuple(self._initial_box_cells)
        self._target_xy = [self._arena.cell_centre(r, c) for r, c in self._targets]
        for k, pad in enumerate(self._pad_ids):
            if k < len(self._targets):
                m.geom_pos[pad] = (*self._target_xy[k], 0.004)
                m.geom_group[pad] = 0
            else:
                m.geom_pos[pad] = (0, 0, _PARKED_Z)
                m.geom_group[pad] = arena_lib.HIDDEN_GROUP
        # The slabs and pads are the world body's geoms, moved here. With
        # sleeping enabled MuJoCo never recomputes a world geom's pose (such
        # geoms cannot move), so they get it here: a world geom's position is
        # its geom_pos (without sleeping mj_kinematics computes the same).
        moved = np.concatenate([self._slab_ids, self._pad_ids])
        self._data.geom_xpos[moved] = m.geom_pos[moved]
        layer = np.zeros((height, width, 4), bool)
        layer[..., WALL] = walls
        for r, c in self._targets:
            layer[r, c, TARGET] = True
        self._static_layer = layer
